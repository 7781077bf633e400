//! The build against brute force: every primitive in one leaf, bounds that hold, depth
//! within its bound, and the same tree at any thread count.
use super::*;
use crate::geometry::testutil::{TestRays, TestRng};
use crate::geometry::{Sphere, Triangle};
use crate::primitives::{Tag, Tagged};

fn random_triangles(n: usize, seed: u64) -> Primitives<f32> {
    let mut rng = TestRng(seed);
    let mut p = Primitives::default();
    for i in 0..n {
        let c = rng.in_cube(50.0);
        let tri = Triangle { v: [0, 1, 2].map(|_| c + rng.in_cube(1.0)) };
        p.triangles.push(Tagged { shape: tri.cast(), tag: Tag { object: 0, face: i as u32, material: 0 } });
    }
    p
}

/// The deepest leaf and the most primitives in one leaf (in any, and in a leaf at the
/// depth bound).
fn leaf_stats(bvh: &Bvh) -> (u32, u32, u32) {
    let (mut deepest, mut largest, mut largest_at_bound) = (0, 0, 0);
    let mut stack = vec![(0usize, 1u32)];
    while let Some((i, d)) = stack.pop() {
        let n = &bvh.nodes[i];
        if n.is_leaf() {
            deepest = deepest.max(d);
            largest = largest.max(n.count);
            if d == MAX_DEPTH {
                largest_at_bound = largest_at_bound.max(n.count);
            }
        } else {
            stack.extend([(i + 1, d + 1), (n.left_or_first as usize, d + 1)]);
        }
    }
    (deepest, largest, largest_at_bound)
}

/// A chain that SAH peels off one primitive at a time, ending in identical triangles
/// ([`crate::scene::procedural::deep_chain_triangles`]): the tree stays within MAX_DEPTH
/// with small leaves, and its walk returns what brute force does. (Before the bound was
/// kept by construction, the chain of 43 over 3000 copies reached depth 48 with a leaf of
/// 94 primitives there, which the GPU's collapse split into three more levels.)
#[test]
fn a_pathologically_deep_input_keeps_the_depth_bound_with_small_leaves() {
    for (chain, cluster) in [(43, 0), (43, 100), (43, 3000), (30, 100_000)] {
        let mut prims = Primitives::<f64>::default();
        for (i, t) in crate::scene::procedural::deep_chain_triangles(chain, cluster).into_iter().enumerate() {
            prims.triangles.push(Tagged { shape: t, tag: Tag { object: 0, face: i as u32, material: 0 } });
        }
        let prims: Primitives<f32> = prims.cast();
        let bvh = Bvh::build(&prims);
        let (deepest, largest, at_bound) = leaf_stats(&bvh);
        eprintln!("chain {chain}, cluster {cluster}: depth {deepest}, leaves up to {largest}, at the bound {at_bound}");
        assert!(deepest <= MAX_DEPTH && bvh.depth == deepest, "depth {deepest} (recorded {})", bvh.depth);
        assert!(
            largest as usize <= SMALL && at_bound as usize <= MAX_LEAF,
            "leaves of {largest}, {at_bound} at the bound"
        );
        // The walk of the GPU's layout (the CPU's walks are strahl-cpu's) finds what brute force finds.
        let gpu = crate::accel::gpu_bvh::GpuBvh::collapse(&bvh, &prims).unwrap();
        let mut rng = TestRng(9);
        for _ in 0..200 {
            // In the plane x = 0 the rays enter the boxes of the whole chain; off it, some.
            let x = if rng.unit() < 0.5 { 0.0 } else { rng.range(0.0, 1.0).powi(20) };
            let o = V3::new(x, rng.range(0.0, 1.0), -1.0);
            let ray = crate::math::Ray::new(o.cast(), (V3::new(x, rng.range(0.0, 1.0), 1.0) - o).normalize().cast());
            assert_eq!(
                crate::accel::gpu_bvh::nearest(&gpu, &prims, &ray, 0.0, f32::INFINITY),
                prims.nearest_brute(&ray, 0.0, f32::INFINITY)
            );
        }
    }
}

#[test]
fn every_primitive_is_in_exactly_one_leaf_inside_its_bounds() {
    // The larger scene is built by several threads, in parts joined at the end.
    for n in [5000, 40_000] {
        let mut prims = random_triangles(n, 1);
        prims
            .spheres
            .push(Tagged { shape: Sphere { center: V3::new(1.0, 2.0, 3.0), radius: 0.5 }, tag: Tag::default() });
        let bvh = Bvh::build(&prims);
        let mut seen = vec![0u32; bvh.prim_refs.len()];
        // Walked from the root: every node is reached once, leaves cover every primitive
        // once, children lie inside their parent, the depth is the longest path.
        let mut reached = 0;
        let mut depth = 0;
        let mut stack = vec![(0usize, 1u32)];
        while let Some((i, d)) = stack.pop() {
            let node = bvh.nodes[i];
            reached += 1;
            depth = depth.max(d);
            if node.is_leaf() {
                for k in node.left_or_first..node.left_or_first + node.count {
                    seen[k as usize] += 1;
                    let (lo, hi) = prims.bounds_f64(bvh.prim_refs[k as usize]);
                    for a in 0..3 {
                        assert!(node.bmin[a] as f64 <= lo[a] && hi[a] <= node.bmax[a] as f64);
                    }
                }
            } else {
                for c in [i + 1, node.left_or_first as usize] {
                    for a in 0..3 {
                        assert!(node.bmin[a] <= bvh.nodes[c].bmin[a] && bvh.nodes[c].bmax[a] <= node.bmax[a]);
                    }
                    stack.push((c, d + 1));
                }
            }
        }
        assert_eq!(reached, bvh.nodes.len());
        assert_eq!(depth, bvh.depth);
        assert!(seen.iter().all(|&s| s == 1));
        let mut refs: Vec<u32> = bvh.prim_refs.iter().map(|r| r.0).collect();
        refs.sort();
        assert!(refs == prims.bounded_refs().map(|r| r.0).collect::<Vec<_>>());
        assert!(bvh.depth <= MAX_DEPTH);
        // A SAH tree over uniformly scattered triangles is shallow.
        assert!(bvh.depth < 30, "depth {}", bvh.depth);
    }
}

#[test]
fn identical_primitives_still_build() {
    let mut p = Primitives::<f32>::default();
    for _ in 0..100 {
        p.spheres.push(Tagged { shape: Sphere { center: V3::zero(), radius: 1.0 }, tag: Tag::default() });
    }
    let bvh = Bvh::build(&p);
    assert!(bvh.nodes.iter().filter(|n| n.is_leaf()).all(|n| n.count <= MAX_LEAF as u32));
}

#[test]
fn empty_scene_builds_an_empty_tree() {
    assert!(Bvh::build(&Primitives::<f32>::default()).is_empty());
}

/// By the 0-1 principle a comparator network sorts every input if it sorts every input
/// of zeros and ones.
#[test]
fn sorting_networks_sort_every_input_of_zeros_and_ones() {
    fn sorts<const N: usize>(net: &[(u8, u8); N], inputs: usize) -> bool {
        (0u32..1 << inputs).all(|bits| {
            let mut keys = [F4::splat(f32::INFINITY); SMALL];
            for (k, key) in keys[..inputs].iter_mut().enumerate() {
                // Lane 0: the bit; lanes 1–3: its complement, sorted as well.
                let b = (bits >> k & 1) as f32;
                *key = F4::new([b, 1.0 - b, b, 1.0 - b]);
            }
            sort_lanes(&mut keys, net);
            let sorted = keys.map(F4::to_array);
            (1..inputs).all(|k| (0..4).all(|lane| sorted[k - 1][lane] <= sorted[k][lane]))
        })
    }
    assert!(sorts(&NET8, 8) && sorts(&NET12, 12));
    // Fewer keys than inputs, padded with +∞ as `decide_small` pads them.
    assert!(sorts(&NET8, 5) && sorts(&NET12, 9));
    // A network cut short does not sort.
    let cut: [(u8, u8); 40] = NET12[..40].try_into().unwrap();
    assert!(!sorts(&cut, 12));
}

/// The split of a small node is the cheapest of all splits of its primitives ordered by
/// centroid on each axis, found here by sorting in f64; of up to `MAX_LEAF` primitives,
/// the cheapest of all splits into two.
#[test]
fn small_nodes_take_the_exact_sah_split() {
    let mut rng = TestRng(7);
    let mut scratch = Bins::new();
    for trial in 0..3000 {
        let n = 2 + trial % (SMALL - 1);
        let mut items: Vec<Item> = (0..n)
            .map(|k| {
                let c = rng.in_cube(10.0);
                let h = rng.in_cube(2.0).abs();
                let (lo, hi) = outward(c - h, c + h);
                Item { lo: [lo[0], lo[1], lo[2], f32::from_bits(k as u32)], hi }
            })
            .collect();
        let span = Span::of(&items);
        let area = |its: &[Item]| Span::of(its).bounds.half_area() as f64;
        let parent = area(&items);
        let cost = |l: &[Item], r: &[Item]| 1.0 + (area(l) * l.len() as f64 + area(r) * r.len() as f64) / parent;
        let mut best = f64::INFINITY;
        for axis in 0..3 {
            let mut sorted = items.clone();
            sorted.sort_by(|a, b| (a.centroid2(axis) as f64).total_cmp(&(b.centroid2(axis) as f64)));
            for mid in 1..n {
                best = best.min(cost(&sorted[..mid], &sorted[mid..]));
            }
        }
        let mut any_split = f64::INFINITY;
        for side in 1..(1u32 << n) - 1 {
            let (l, r): (Vec<Item>, Vec<Item>) =
                (0..n).map(|k| (side >> k & 1 != 0, items[k])).fold((vec![], vec![]), |(mut l, mut r), (left, it)| {
                    if left {
                        l.push(it)
                    } else {
                        r.push(it)
                    }
                    (l, r)
                });
            any_split = any_split.min(cost(&l, &r));
        }
        if n <= MAX_LEAF {
            assert!(any_split <= best);
            best = any_split;
        }
        match decide(&mut items, &span, 1, &mut scratch) {
            Decision::Leaf => assert!(n <= MAX_LEAF && best >= n as f64 * (1.0 - 1e-6), "n {n}: leaf, best {best}"),
            Decision::Split { mid, left, right } => {
                let got = cost(&items[..mid], &items[mid..]);
                assert!((got - best).abs() <= 1e-5 * best, "n {n}: split costs {got}, best {best}");
                let (l, r) = (Span::of(&items[..mid]), Span::of(&items[mid..]));
                assert_eq!(left.bounds.half_area(), l.bounds.half_area());
                assert_eq!(right.bounds.half_area(), r.bounds.half_area());
            }
        }
        // The items were only reordered.
        let mut after: Vec<u32> = items.iter().map(|it| it.prim().0).collect();
        after.sort();
        assert_eq!(after, (0..n as u32).collect::<Vec<_>>());
    }
}
