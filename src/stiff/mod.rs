//! The stiff and extreme numerical cases (`strahl stiff`): each case runs the robust code on
//! the CPU (f32) and the GPU, and the textbook code on the CPU, against an oracle, and
//! reports one row per (case, variant).
//!
//! What a row counts:
//! - `disagree`: rays whose hit/miss (or number of roots) differs from the oracle, among rays
//!   the oracle decides clearly (not within a relative 1e-6 of tangency or of an edge);
//! - `rel t`: relative error of t against the oracle, over roots both agree on;
//! - `ulps`: distance of the hit point from the exact point, in ULPs of its largest coordinate;
//! - `fails`: what the case exists to catch — re-hits of the surface a spawned ray starts on,
//!   escapes from a closed mesh, NaN outputs or false hits, acne or hole pixels;
//! - `ns/ray`: time per ray of the whole variant (on the GPU: wall time of the dispatches and
//!   readback, so small cases are dominated by overhead).

pub mod cases;
pub mod oracle;
pub mod textbook;

use std::fmt::Write as _;

/// Which implementation a row measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variant {
    /// The robust code on the CPU (f32, the GPU's mirror).
    Cpu,
    /// The robust code in WGSL on the GPU.
    Gpu,
    /// The textbook formulation, on the CPU in f32.
    Textbook,
}

impl Variant {
    pub fn name(self) -> &'static str {
        match self {
            Variant::Cpu => "robust cpu",
            Variant::Gpu => "robust gpu",
            Variant::Textbook => "textbook cpu",
        }
    }
}

/// One line of the table.
#[derive(Clone, Debug, Default)]
pub struct Row {
    pub case: String,
    pub variant: Option<Variant>,
    pub rays: usize,
    pub disagree: usize,
    pub rel_t: Stats,
    pub ulps: Stats,
    pub fails: usize,
    /// What `fails` counts in this case.
    pub fail_kind: &'static str,
    pub ns_per_ray: f64,
}

/// Max and median of a sample of errors.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    pub max: f64,
    pub median: f64,
    pub count: usize,
}

impl Stats {
    pub fn of(mut v: Vec<f64>) -> Stats {
        if v.is_empty() {
            return Stats::default();
        }
        v.sort_by(f64::total_cmp);
        Stats { max: v[v.len() - 1], median: v[v.len() / 2], count: v.len() }
    }
}

/// Relative error of `got` against `exact`.
pub fn rel_err(got: f64, exact: f64) -> f64 {
    (got - exact).abs() / exact.abs().max(f64::MIN_POSITIVE)
}

/// Distance of `got` from `exact` in ULPs (f32) of the largest coordinate of `exact`.
pub fn ulps(got: strahl_core::math::V3<f32>, exact: strahl_core::math::V3<f64>) -> f64 {
    let m = exact.abs().max_component().max(f32::MIN_POSITIVE as f64) as f32;
    let ulp = (m.next_up() - m) as f64;
    (got.to_f64() - exact).abs().max_component() / ulp
}

/// The table as Markdown.
pub fn table(rows: &[Row]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| case | variant | rays | disagree | max rel t | median rel t | max ulps | median ulps | fails | ns/ray |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        let stat = |st: &Stats, f: &dyn Fn(f64) -> String| {
            if st.count == 0 { ("-".to_string(), "-".to_string()) } else { (f(st.max), f(st.median)) }
        };
        let (tmax, tmed) = stat(&r.rel_t, &|v| format!("{v:.1e}"));
        let (umax, umed) = stat(&r.ulps, &|v| format!("{v:.1}"));
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} {} | {:.0} |",
            r.case,
            r.variant.map_or("-", Variant::name),
            r.rays,
            r.disagree,
            tmax,
            tmed,
            umax,
            umed,
            r.fails,
            r.fail_kind,
            r.ns_per_ray
        );
    }
    s
}
