//! Guide tables: the searches of a cumulative distribution that pick an emitter
//! ([`strahl_core::render::emitters::select`]) and an environment map's row and column
//! (`environment::find_cell`), in lanes, in a step or two where the halving searches take
//! log₂ of the table's length, each step a load per lane that waits on the one before.
//!
//! The method is the "cutpoint" or guide-table method (Chen & Asau, "On generating random
//! variates from an empirical distribution", AIIE Transactions 6(2), 1974; Devroye,
//! "Non-Uniform Random Variate Generation", 1986, §III.2.4). Every search here counts the
//! entries `c` of a non-decreasing table with `!(u < c)`, which is what both scalar searches
//! return (their halving finds where that predicate turns false; for a NaN `u` it holds
//! everywhere, and both return the table's length). With K buckets, K a power of two, bucket
//! k < K holds the u in [k/K, (k+1)/K) (and bucket 0 the negative ones), bucket K the u ≥ 1
//! and NaN. `u·K` and `k/K` are exact in f32 (scaling by a power of two), so the bucket of u
//! is exact and the count lies between the bucket's two starts:
//!
//! - `start[0] = 0`, `start[k] = #{c ≤ k/K}` for 1 ≤ k ≤ K, `start[K + 1] = n`;
//! - for u in bucket k: `start[k] ≤ count(u) ≤ start[k + 1]`.
//!
//! A halving search between the two starts then finds the count itself. So the answer is the
//! scalar search's, exactly, whatever the table and whatever u: no rounding enters. With K
//! four times the table's length (rounded up to a power of two; once the length only, for
//! tables of more than 2¹⁶ entries in all, whose starts would then outgrow the caches), most
//! ranges hold no entry or one, so the lanes, which step together until the last of them is
//! done, mostly take one step; ties (a run of zero-probability entries) only lengthen the
//! search of the bucket they fall in, to its log₂.

// Lane loops index several arrays with the lane: the form the compiler turns into vector
// instructions.
#![allow(clippy::needless_range_loop)]

use strahl_core::layout::{FlatEnvironment, FlatScene};
use strahl_core::math::lanes::F;
use strahl_core::render::environment::cell_pdf;

/// The guides of a scene's distributions, made once per render.
#[derive(Clone, Debug, Default)]
pub(super) struct Guides {
    /// The emitters' cdf but its last entry (`emitters::select` never compares that).
    pub emitters: Option<Guide>,
    /// An environment map's rows (the marginal's inner edges) and each row's columns (its
    /// conditional's inner edges): what `environment::find_cell` compares.
    pub env: Option<(Guide, Guide)>,
    /// The map's cell densities (`environment::cell_pdf`, computed once here), row by row;
    /// empty without a map.
    pub env_pdf: Vec<f32>,
}

impl Guides {
    /// The guides of `g`'s emitters and of `env`, its environment map where the lanes sample
    /// it ([`super::environment::map`]).
    pub fn new(g: &FlatScene, env: Option<&FlatEnvironment>) -> Self {
        let emitters =
            (!g.emitters.is_empty()).then(|| Guide::new(1, g.emitters.len() - 1, |_, i| g.emitters[i].cdf)).flatten();
        let env_pdf = match env {
            Some(e)
                if g.env_distribution.len() >= e.height as usize + 1 + e.height as usize * (e.width as usize + 1) =>
            {
                let (w, h) = (e.width as usize, e.height as usize);
                (0..h).flat_map(|j| (0..w).map(move |i| cell_pdf(g, e, i, j))).collect()
            }
            _ => Vec::new(),
        };
        let env = env.and_then(|e| {
            let (w, h) = (e.width as usize, e.height as usize);
            let d = &g.env_distribution;
            if w == 0 || h == 0 || d.len() < h + 1 + h * (w + 1) {
                return None;
            }
            let rows = Guide::new(1, h - 1, |_, i| d[1 + i])?;
            let columns = Guide::new(h, w - 1, |j, i| d[h + 1 + j * (w + 1) + 1 + i])?;
            Some((rows, columns))
        });
        Self { emitters, env, env_pdf }
    }
}

/// The most entries (all tables together) whose guides get four buckets an entry; larger ones
/// get one.
const FINE_UP_TO: usize = 1 << 16;

/// Guide tables of one or more distributions of equal length, back to back.
#[derive(Clone, Debug)]
pub(super) struct Guide {
    /// The searched values of every table, `len` each.
    values: Vec<f32>,
    len: usize,
    /// K, a power of two.
    buckets: usize,
    /// Per table, K + 2 bucket starts (counts into the table).
    starts: Vec<u32>,
}

impl Guide {
    /// The guide of `tables` tables of `len` values each (non-decreasing within each),
    /// `value(t, i)` being table t's entry i; None where a value is not a number or a table
    /// falls (the scalar searches' answers then need not be a count), or where the tables are
    /// too long to count in u32.
    pub(super) fn new(tables: usize, len: usize, value: impl Fn(usize, usize) -> f32) -> Option<Self> {
        if tables.saturating_mul(len) >= u32::MAX as usize / 2 {
            return None;
        }
        let fine = if tables * len <= FINE_UP_TO { 4 } else { 1 };
        let buckets = len.max(1).next_power_of_two() * fine;
        let mut values = Vec::with_capacity(tables * len);
        let mut starts = Vec::with_capacity(tables * (buckets + 2));
        for t in 0..tables {
            let first = values.len();
            values.extend((0..len).map(|i| value(t, i)));
            let c = &values[first..];
            if c.iter().any(|v| v.is_nan()) || c.windows(2).any(|w| w[1] < w[0]) {
                return None;
            }
            starts.push(0);
            let mut i = 0;
            for k in 1..=buckets {
                let edge = k as f32 / buckets as f32;
                while i < len && c[i] <= edge {
                    i += 1;
                }
                starts.push(i as u32);
            }
            starts.push(len as u32);
        }
        Some(Self { values, len, buckets, starts })
    }

    /// Values per table.
    pub(super) fn len(&self) -> usize {
        self.len
    }

    /// For each lane l, the number of entries `c` of table `table[l]` with `!(u < c)` (table
    /// numbers past the last read table 0's).
    #[inline(always)]
    pub(super) fn count<const N: usize>(&self, table: [usize; N], u: F<N>) -> [usize; N] {
        let k = self.buckets;
        let tables = self.starts.len() / (k + 2);
        let (mut lo, mut hi, mut base) = ([0u32; N], [0u32; N], [0u32; N]);
        for l in 0..N {
            let t = if table[l] < tables { table[l] } else { 0 };
            let x = u.0[l];
            // (x · K is exact: K is a power of two; below 1 it stays below K.)
            let b = if x < 0.0 {
                0
            } else if x < 1.0 {
                ((x * k as f32) as usize).min(k - 1)
            } else {
                k
            };
            let s = t * (k + 2) + b;
            (lo[l], hi[l]) = (self.starts[s], self.starts[s + 1]);
            base[l] = (t * self.len) as u32;
        }
        // Halving between the starts, each lane in its own range, all stepping together
        // without branches (a lane whose range is empty reads an entry in bounds and keeps
        // its count).
        let Some(last) = self.values.len().checked_sub(1) else {
            return [0; N];
        };
        while (0..N).fold(false, |any, l| any | (lo[l] < hi[l])) {
            for l in 0..N {
                let active = lo[l] < hi[l];
                let mid = lo[l] + (hi[l] - lo[l]) / 2;
                let below = u.0[l] < self.values[((base[l] + mid) as usize).min(last)];
                hi[l] = if active & below { mid } else { hi[l] };
                lo[l] = if active & !below { mid + 1 } else { lo[l] };
            }
        }
        lo.map(|c| c as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use strahl_core::render::sampler::Sampler;

    const N: usize = 16;

    /// What the scalar searches count: the entries with !(u < c), one after the other.
    fn counted(c: &[f32], u: f32) -> usize {
        c.iter().filter(|&&v| !(u < v)).count()
    }

    /// Every lane counts what a walk over the table counts, on tables with ties, zero steps,
    /// a last value above and below 1, lengths 0 to 40 and a few longer ones (past
    /// [`FINE_UP_TO`] in all, where the buckets are coarser), one table or three at once, and
    /// numbers on the values, on the bucket edges, between, below 0, at and above 1, and NaN.
    #[test]
    fn counts_equal_a_walk_over_the_table() {
        let mut rng = Sampler::new(7, 1, 2);
        for len in (0..=40usize).chain([63, 64, 65, 200, 30_000]) {
            for shape in 0..4 {
                let tables: Vec<Vec<f32>> = (0..3)
                    .map(|_| {
                        let mut s = 0.0f32;
                        let w: Vec<f32> = (0..len)
                            .map(|i| match shape {
                                0 => 1.0,
                                1 => (i % 3 == 0) as u32 as f32,
                                2 => rng.next_f32() * rng.next_f32(),
                                _ => (i >= len / 2) as u32 as f32 * 5.0,
                            })
                            .collect();
                        let total: f32 = w.iter().sum::<f32>().max(1e-30);
                        let scale = if shape == 3 { 1.0000001 } else { 1.0 };
                        w.iter()
                            .map(|x| {
                                s += x;
                                s / total * scale
                            })
                            .collect()
                    })
                    .collect();
                for n_tables in [1, 3] {
                    let g = Guide::new(n_tables, len, |t, i| tables[t][i]).expect("a guide");
                    assert_eq!(g.len(), len);
                    let mut us: Vec<f32> = tables[..n_tables].iter().flatten().copied().collect();
                    us.extend(tables[..n_tables].iter().flatten().flat_map(|&v| [v.next_down(), v.next_up()]));
                    if us.len() > 3000 {
                        // (A walk over a long table per number: a sample of them.)
                        us = (0..3000).map(|_| us[(rng.next_f32() * us.len() as f32) as usize % us.len()]).collect();
                    }
                    let k = g.buckets;
                    assert!(k >= len, "{k} buckets for {len} entries");
                    us.extend((0..=k.min(4096)).map(|b| b as f32 / k as f32));
                    us.extend((0..64).map(|_| rng.next_f32()));
                    us.extend([-0.5, -0.0, 0.0, 1.0, 1.5, f32::NAN, f32::INFINITY, f32::NEG_INFINITY]);
                    for chunk in us.chunks(N) {
                        let mut u = [0.5f32; N];
                        u[..chunk.len()].copy_from_slice(chunk);
                        let table: [usize; N] = std::array::from_fn(|l| l % n_tables);
                        let got = g.count(table, F(u));
                        for l in 0..N {
                            let want = counted(&tables[l % n_tables], u[l]);
                            assert_eq!(got[l], want, "len {len}, shape {shape}, {n_tables} tables, u {}", u[l]);
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn tables_out_of_order_or_not_numbers_have_no_guide() {
        assert!(Guide::new(1, 3, |_, i| [0.5, 0.25, 1.0][i]).is_none());
        assert!(Guide::new(1, 2, |_, i| [0.5, f32::NAN][i]).is_none());
        assert!(Guide::new(2, 2, |t, i| [[0.5, 1.0], [0.75, 0.5]][t][i]).is_none());
    }
}
