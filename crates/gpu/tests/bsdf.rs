//! The shaders' BSDFs (`shaders/modules/bsdf.wgsl`, run by the BSDF probe,
//! `strahl_gpu::bsdf_probe`) against their CPU twin (`strahl_core::render::bsdf`) for the same
//! uniform numbers, in a white furnace, and in a χ² test of the device's sampling against its
//! own density (`strahl_core::testutil::chi2_sphere`, the test of Mitsuba's and pbrt's test
//! suites). The materials are a scene file's `[[materials]]` ([`MATERIALS`]), one sphere each,
//! flattened and uploaded as for a render, so the probe reads them with the shaders'
//! `load_material` and is composed with the key a render of them has.
//!
//! Without an adapter the tests fail, unless `STRAHL_SKIP_GPU_TESTS=1` asks them to skip, which
//! each records (`SKIPPED <test>: <why>`, as `tests/common` does for the root crate's tests).

use std::path::Path;
use std::sync::{Mutex, OnceLock};
use std::time::Instant;
use strahl_core::layout::FlatMaterial;
use strahl_core::math::V3;
use strahl_core::render::Prepared;
use strahl_core::render::bsdf;
use strahl_core::render::pbr::MIN_PBR_ALPHA;
use strahl_core::render::sampler::Sampler;
use strahl_core::scene::MaterialKind;
use strahl_core::testutil::{chi2_directions, chi2_sphere};
use strahl_gpu::bsdf_probe::{BsdfProbe, ProbePoint, ProbeSample};
use strahl_gpu::{GpuContext, SceneBuffers};

/// The materials probed: a name and the keys of its scene-file `[[materials]]` table
/// (docs/src/scene-files.md). Every test below runs on all of them or names those it runs on;
/// a material added here is compared with the CPU at once.
const MATERIALS: &[(&str, &str)] = &[
    ("diffuse", "type = \"diffuse\"\ncolor = [0.8, 0.5, 0.3]"),
    ("rough mirror", "type = \"mirror\"\ncolor = [0.9, 0.7, 0.5]\nroughness = 0.3"),
    ("pbr metal", "type = \"pbr\"\ncolor = [0.9, 0.6, 0.3]\nmetallic = 1.0\nroughness = 0.4"),
    ("pbr plastic", "type = \"pbr\"\ncolor = [0.2, 0.5, 0.8]\nmetallic = 0.0\nroughness = 0.5"),
    ("pbr blend", "type = \"pbr\"\ncolor = [0.7, 0.7, 0.2]\nmetallic = 0.5\nroughness = 0.7"),
    ("pbr smooth", "type = \"pbr\"\ncolor = [0.5, 0.5, 0.5]\nmetallic = 0.0\nroughness = 0.1"),
    ("rough glass", "type = \"dielectric\"\nroughness = 0.4"),
    ("pbr glass", "type = \"pbr\"\ncolor = [1.0, 1.0, 1.0]\ntransmission = 1.0\nroughness = 0.6"),
    ("pbr half glass", "type = \"pbr\"\ncolor = [1.0, 1.0, 1.0]\ntransmission = 0.5\nroughness = 0.5"),
    ("smooth pbr glass", "type = \"pbr\"\ncolor = [1.0, 1.0, 1.0]\ntransmission = 1.0\nroughness = 0.05"),
    (
        "tinted pbr glass",
        "type = \"pbr\"\ncolor = [0.9, 0.6, 0.4]\ntransmission = 0.5\nmetallic = 0.2\nroughness = 0.3\nior = 1.33",
    ),
    ("white pbr dielectric", "type = \"pbr\"\ncolor = [1.0, 1.0, 1.0]\nmetallic = 0.0\nroughness = 0.5"),
    ("white pbr metal", "type = \"pbr\"\ncolor = [1.0, 1.0, 1.0]\nmetallic = 1.0\nroughness = 0.3"),
    (
        "coated velvet",
        "type = \"pbr\"\ncolor = [0.6, 0.1, 0.1]\nroughness = 0.6\nclearcoat = 1.0\nclearcoat_roughness = 0.1\n\
         sheen_color = [1.0, 0.7, 0.3]\nsheen_roughness = 0.5",
    ),
    (
        "tinted specular",
        "type = \"pbr\"\ncolor = [0.3, 0.3, 0.3]\nroughness = 0.4\nior = 1.8\nspecular = 0.8\nspecular_color = [1.0, 0.5, 0.2]",
    ),
    (
        "white layers",
        "type = \"pbr\"\ncolor = [1.0, 1.0, 1.0]\nroughness = 0.5\nclearcoat = 1.0\nclearcoat_roughness = 0.3\n\
         sheen_color = [1.0, 1.0, 1.0]\nsheen_roughness = 0.6",
    ),
    (
        "white coated glass",
        "type = \"pbr\"\ncolor = [1.0, 1.0, 1.0]\nroughness = 0.3\ntransmission = 1.0\nclearcoat = 0.7\n\
         clearcoat_roughness = 0.2\nsheen_color = [1.0, 1.0, 1.0]\nsheen_roughness = 0.8",
    ),
];

/// The white materials of the furnace: every one reflects and transmits all light.
const FURNACE: &[&str] = &[
    "rough glass",
    "pbr glass",
    "pbr half glass",
    "smooth pbr glass",
    "white pbr dielectric",
    "white pbr metal",
    "white layers",
    "white coated glass",
];

/// The χ² cases: a material, cos θ_o, and whether wo lies on the front face's side.
const CHI2: &[(&str, f32, bool)] = &[
    ("rough mirror", 0.6, true),
    ("pbr blend", 0.8, true),
    ("rough glass", 0.7, true),
    ("rough glass", 0.8, false),
    ("pbr half glass", 0.5, true),
    ("pbr half glass", 0.6, false),
    ("coated velvet", 0.7, true),
    ("white coated glass", 0.5, true),
];

/// The scene file of [`MATERIALS`]: one sphere of each in a row.
fn scene_file() -> String {
    let mut s = String::from(
        "[camera]\neye = [0.0, 0.0, -10.0]\nlook_at = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 40.0\n\
         [image]\nwidth = 8\nheight = 8\n",
    );
    for (name, keys) in MATERIALS {
        s += &format!("[[materials]]\nname = \"{name}\"\n{keys}\n");
    }
    for (k, (name, _)) in MATERIALS.iter().enumerate() {
        s += &format!(
            "[[objects]]\ntype = \"sphere\"\ncenter = [{}.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"{name}\"\n",
            3 * k
        );
    }
    s
}

/// The device, the scene of [`MATERIALS`] on it and the probe compiled for it, shared by the
/// tests (the probe compiles once).
struct Fixture {
    ctx: GpuContext,
    prep: Prepared,
    scene: SceneBuffers,
    probe: BsdfProbe,
    /// Held while a test uses the device. The tests' threads submitting and waiting on the one
    /// device at once stalled for 50 s on lavapipe (Mesa 25.0) at their first dispatches; one
    /// at a time they run without (and lavapipe runs each dispatch on every core anyway).
    turn: Mutex<()>,
}

impl Fixture {
    /// The index and flattened form of material `name`.
    fn material(&self, name: &str) -> (u32, FlatMaterial) {
        let i = self.prep.scene.materials.iter().position(|m| m.name == name).unwrap_or_else(|| panic!("no {name}"));
        (i as u32, self.prep.flat.materials[i])
    }

    /// The device's samples for `inputs`.
    fn sample(&self, inputs: &[(ProbePoint, [f32; 3])]) -> Vec<ProbeSample> {
        let _turn = self.turn.lock().unwrap_or_else(|e| e.into_inner());
        self.probe.sample(&self.ctx, &self.scene, inputs).unwrap_or_else(|e| panic!("{e}"))
    }

    /// The device's densities over the whole sphere for `inputs` (`ProbeEval::density`).
    fn density(&self, inputs: &[(ProbePoint, V3<f32>)]) -> Vec<f32> {
        let _turn = self.turn.lock().unwrap_or_else(|e| e.into_inner());
        let evals = self.probe.eval(&self.ctx, &self.scene, inputs).unwrap_or_else(|e| panic!("{e}"));
        evals.iter().map(|e| e.density).collect()
    }
}

static FIXTURE: OnceLock<Result<Fixture, String>> = OnceLock::new();

/// The shared [`Fixture`]. Without an adapter the test fails with wgpu's reason, unless
/// `STRAHL_SKIP_GPU_TESTS=1`: then the skip is recorded ([`skip`]) and None returned. With
/// `STRAHL_EXPECT_ADAPTER` set, an adapter of another name fails the test.
fn fixture() -> Option<&'static Fixture> {
    let f = FIXTURE.get_or_init(|| {
        let ctx = GpuContext::new().map_err(|e| e.to_string())?;
        let scene = strahl_core::scene::file::parse(&scene_file(), Path::new("bsdf.toml"), Path::new("."))
            .unwrap_or_else(|e| panic!("the probe's scene: {e}"));
        let prep = Prepared::new(scene);
        let scene = SceneBuffers::upload(&ctx, &prep.flat).unwrap_or_else(|e| panic!("{e}"));
        let start = Instant::now();
        let probe = BsdfProbe::new(&ctx, &scene).unwrap_or_else(|e| panic!("{e}"));
        eprintln!(
            "the BSDF probe for {} compiled in {:.1} s on {}",
            probe.key().label(),
            start.elapsed().as_secs_f64(),
            ctx.adapter_name()
        );
        Ok(Fixture { ctx, prep, scene, probe, turn: Mutex::new(()) })
    });
    match f {
        Ok(f) => {
            if let Ok(want) = std::env::var("STRAHL_EXPECT_ADAPTER") {
                let info = &f.ctx.adapter_info;
                assert!(
                    info.name.to_lowercase().contains(&want.to_lowercase()),
                    "STRAHL_EXPECT_ADAPTER={want}, but the tests got {}",
                    strahl_gpu::instance::describe(info)
                );
            }
            Some(f)
        }
        Err(e) if std::env::var("STRAHL_SKIP_GPU_TESTS").is_ok_and(|v| v == "1") => {
            skip(&format!("no GPU: {e}"));
            None
        }
        Err(e) => panic!("{e} (set STRAHL_SKIP_GPU_TESTS=1 to skip GPU tests)"),
    }
}

/// Records that the running test skipped its checks, as `tests/common` does: a line
/// `SKIPPED <test>: <why>` on standard error, appended to the file `STRAHL_SKIP_LOG` names
/// where set (`.ci/run` fails on any).
fn skip(why: &str) {
    let test = std::thread::current().name().unwrap_or("a test").to_string();
    let line = format!("SKIPPED {test}: {why}");
    eprintln!("{line}");
    if let Some(log) = std::env::var_os("STRAHL_SKIP_LOG") {
        use std::io::Write;
        let appended =
            std::fs::OpenOptions::new().create(true).append(true).open(&log).and_then(|mut f| writeln!(f, "{line}"));
        appended.unwrap_or_else(|e| panic!("cannot record the skip in {}: {e}", Path::new(&log).display()));
    }
}

/// Whether material `m` lets light through (a dielectric, or pbr with transmission): its
/// tests run from both sides.
fn transmits(m: &FlatMaterial) -> bool {
    m.kind() == MaterialKind::Dielectric || (m.kind() == MaterialKind::Pbr && m.transmission > 0.0)
}

/// The direction at cos θ = `cos` from unit `ns`, at azimuth `phi` about it.
fn around(ns: V3<f32>, cos: f32, phi: f32) -> V3<f32> {
    let a = if ns.x.abs() < 0.9 { V3::new(1.0, 0.0, 0.0) } else { V3::new(0.0, 1.0, 0.0) };
    let t = ns.cross(a).normalize();
    let b = ns.cross(t);
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    (ns * cos + (t * phi.cos() + b * phi.sin()) * sin).normalize()
}

/// `n` probe inputs at `p` with uniform numbers from the stream `stream`.
fn draws(p: ProbePoint, n: usize, stream: u32) -> Vec<(ProbePoint, [f32; 3])> {
    let mut rng = Sampler::new(stream, 0, 17);
    (0..n).map(|_| (p, [rng.next_f32(), rng.next_f32(), rng.next_f32()])).collect()
}

/// `n` probe inputs at `p` with the quasi-random points of Roberts's R3 sequence (the
/// Kronecker sequence of the plastic number's powers, "The Unreasonable Effectiveness of
/// Quasirandom Sequences", 2018), shifted by a random offset: an integral over them converges
/// much faster than over independent numbers, so that a furnace of few samples resolves 1 %.
fn quasi_draws(p: ProbePoint, n: usize, stream: u32) -> Vec<(ProbePoint, [f32; 3])> {
    const PHI3: f64 = 1.220_744_084_605_759_5;
    let step = [1.0 / PHI3, 1.0 / (PHI3 * PHI3), 1.0 / (PHI3 * PHI3 * PHI3)];
    let mut rng = Sampler::new(stream, 1, 17);
    let shift = [rng.next_f32() as f64, rng.next_f32() as f64, rng.next_f32() as f64];
    // The largest f32 below 1: a number rounded up to 1 would leave [0, 1).
    let below_one = 1.0 - f32::EPSILON / 2.0;
    let at = |i: usize, k: usize| ((shift[k] + i as f64 * step[k]).fract() as f32).min(below_one);
    (0..n).map(|i| (p, [at(i, 0), at(i, 1), at(i, 2)])).collect()
}

/// The relative difference of `a` and `b`: to the larger magnitude, at least `floor`.
fn rel(a: f32, b: f32, floor: f32) -> f32 {
    (a - b).abs() / a.abs().max(b.abs()).max(floor)
}

/// The largest difference of a component of `a` and `b`, relative to their largest magnitude
/// (at least `floor`).
fn rel3(a: V3<f32>, b: V3<f32>, floor: f32) -> f32 {
    let m = a.to_array().into_iter().chain(b.to_array()).fold(floor, |m, v| m.max(v.abs()));
    (a - b).to_array().iter().fold(0.0f32, |e, d| e.max(d.abs() / m))
}

/// Relative tolerance of the GPU's values against the CPU's.
const REL: f32 = 1e-4;

/// The tolerance of a sample of `m` against the CPU's: [`REL`], or where the material's GGX
/// lobe is sharp (α small), what f32 can promise there. D(h) changes by 2/α² relative per unit
/// of cos² θ_h at its peak, so the few ulps by which the two backends' h differ (their sines
/// and cosines differ in the last bits) are amplified to ~2ε/α² in the densities; 8ε/α² allows
/// four ulps. It is REL for α ≥ 0.1; for the smoothest pbr lobes here (α 0.01, 0.0025; a
/// coat's α 0.01, 0.04) it is 1 %, 15 % and 0.1 %. (The half vector's normalisation differs in its last bits too, so even
/// `bsdf_eval` at the same direction differs that much there.)
fn tolerance(m: &FlatMaterial) -> f32 {
    // A clear coat's lobe counts as well (its own roughness).
    let coat = if m.clearcoat > 0.0 { m.clearcoat_roughness * m.clearcoat_roughness } else { 1.0 };
    let alpha = match m.kind() {
        MaterialKind::Pbr => (m.roughness * m.roughness).min(coat).max(MIN_PBR_ALPHA),
        MaterialKind::Mirror | MaterialKind::Dielectric if m.roughness >= bsdf::MIN_ROUGHNESS => m.roughness,
        _ => 1.0,
    };
    REL.max(8.0 * f32::EPSILON / (alpha * alpha))
}

/// The share of samples allowed to disagree (a lobe chosen the other way where the uniform
/// number falls within rounding of a lobe's probability, or a value past [`REL`] where the
/// formulas amplify rounding: grazing directions, a microfacet at the edge of the lobe).
const OUTLIERS: f64 = 2e-3;

/// How one material's samples compared: counts, and the largest relative differences of
/// direction, weight, density, and `bsdf_eval`'s f·cos and density at the direction.
#[derive(Default)]
struct Agreement {
    samples: usize,
    outliers: usize,
    flags: usize,
    worst: [f32; 5],
    /// The largest relative difference of the GPU's `bsdf_eval` (f·cos, density) and the
    /// CPU's `eval` at the GPU's direction, and how many exceed the tolerance.
    same_dir: f32,
    same_dir_off: usize,
    first: Option<String>,
}

/// For the same uniform numbers, the device's sample is the CPU's: the same flags, the
/// direction, weight and density within [`REL`], and `bsdf_eval` at it within [`REL`] of the
/// CPU's `eval`; for every material of [`MATERIALS`], at normal to grazing incidence, from
/// both sides where it transmits, about a normal along +z and a tilted one (the shading
/// basis's other branch). Also the device agrees with itself: a reflected sample's density
/// and weight are what its `bsdf_eval` gives.
#[test]
fn gpu_samples_equal_the_cpu_samples() {
    let Some(f) = fixture() else { return };
    let start = Instant::now();
    const PER_CASE: usize = 1024;
    let mut inputs = Vec::new();
    let mut labels = Vec::new();
    for &(name, _) in MATERIALS {
        let (material, m) = f.material(name);
        let fronts: &[bool] = if transmits(&m) { &[true, false] } else { &[true] };
        for ns in [V3::new(0.0, 0.0, 1.0), V3::new(0.36, -0.48, -0.8)] {
            for (k, cos) in [0.95f32, 0.6, 0.3, 0.08].into_iter().enumerate() {
                for &front in fronts {
                    let wo = around(ns, cos, 0.7 + k as f32);
                    let p = ProbePoint { material, wo, ns, front };
                    inputs.extend(draws(p, PER_CASE, labels.len() as u32));
                    labels.push((name, format!("{name} cos {cos} front {front} ns {ns:?}")));
                }
            }
        }
    }
    let gpu = f.sample(&inputs);
    let gpu_time = start.elapsed().as_secs_f64();
    let mut by_material: Vec<(&str, Agreement)> = MATERIALS.iter().map(|&(n, _)| (n, Agreement::default())).collect();
    let (mut self_off, mut reflected) = (0usize, 0usize);
    for (k, ((p, u), g)) in inputs.iter().zip(&gpu).enumerate() {
        let (name, label) = &labels[k / PER_CASE];
        let a = &mut by_material.iter_mut().find(|(n, _)| n == name).unwrap().1;
        a.samples += 1;
        let m = f.prep.flat.materials[p.material as usize];
        let cpu = bsdf::sample(&m, p.wo, p.ns, p.front, *u);
        let same = match cpu {
            None => !g.valid,
            Some(c) if g.valid && c.through == g.through && c.specular == g.specular => {
                let (f_cos, pdf) = bsdf::eval(&m, p.wo, c.dir, p.ns, p.front);
                let errors = [
                    rel3(g.dir, c.dir, 1.0),
                    rel3(g.weight, c.weight, 1e-3),
                    rel(g.pdf, c.pdf, 1e-3),
                    rel3(g.f_cos, f_cos, 1e-3),
                    rel(g.eval_pdf, pdf, 1e-3),
                ];
                for (w, e) in a.worst.iter_mut().zip(errors) {
                    *w = w.max(e);
                }
                // The same formulas at the same direction: no sampling difference to amplify.
                let (f_at, pdf_at) = bsdf::eval(&m, p.wo, g.dir, p.ns, p.front);
                let e = rel3(g.f_cos, f_at, 1e-3).max(rel(g.eval_pdf, pdf_at, 1e-3));
                a.same_dir = a.same_dir.max(e);
                a.same_dir_off += (e > tolerance(&m)) as usize;
                errors.iter().all(|&e| e <= tolerance(&m))
            }
            Some(_) => false,
        };
        if !same {
            a.outliers += 1;
            a.flags += (cpu.is_some() != g.valid || cpu.is_some_and(|c| c.through != g.through)) as usize;
            a.first.get_or_insert_with(|| format!("{label}: u {u:?}: GPU {g:?}, CPU {cpu:?}"));
        }
        if g.valid && !g.through && !g.specular {
            // The sampler's density is the density bsdf_eval gives, and its weight eval/pdf
            // (to f32 rounding of the two ways of computing them, as the CPU's tests allow).
            reflected += 1;
            let weight = g.f_cos * (1.0 / g.eval_pdf);
            if !(rel(g.eval_pdf, g.pdf, 1e-3) <= 2e-3
                && rel3(weight, g.weight, 1e-3) <= 2e-3
                && g.density == g.eval_pdf)
            {
                self_off += 1;
            }
        }
    }
    let outliers: usize = by_material.iter().map(|(_, a)| a.outliers).sum();
    let mut failed = Vec::new();
    for (name, a) in &by_material {
        let [d, w, p, fc, ep] = a.worst;
        let tol = tolerance(&f.material(name).1);
        eprintln!(
            "GPU = CPU {name:>20}: {:>3} of {:>5} outside {tol:.0e} ({} other flags); worst dir {d:.1e} weight {w:.1e} \
             pdf {p:.1e} eval {fc:.1e} eval pdf {ep:.1e}; eval at the GPU's direction {:.1e} ({} outside)",
            a.outliers, a.samples, a.flags, a.same_dir, a.same_dir_off
        );
        if a.outliers as f64 > OUTLIERS * a.samples as f64 || a.same_dir_off as f64 > OUTLIERS * a.samples as f64 {
            failed.push(a.first.clone().unwrap_or_else(|| format!("{name}: at the GPU's direction")));
        }
    }
    let share = outliers as f64 / inputs.len() as f64;
    eprintln!(
        "GPU = CPU: {} of {} samples ({} cases) agree within their tolerance ({share:.2e} outliers); {self_off} of {reflected} \
         reflected samples off their own eval; {:.1} s ({gpu_time:.1} s on the device)",
        inputs.len() - outliers,
        inputs.len(),
        labels.len(),
        start.elapsed().as_secs_f64()
    );
    assert!(failed.is_empty(), "materials with more than {OUTLIERS} of their samples off, first of each: {failed:#?}");
    assert!((self_off as f64) <= OUTLIERS * reflected as f64, "{self_off} of {reflected} samples off their own eval");
}

/// The white furnace on the device: a white material of [`FURNACE`] scatters all light, so
/// the mean weight of its samples is 1 within 1 % (transmitted weights times η², undoing the
/// radiance's compression into the denser side, as the CPU's furnace does), at normal to
/// grazing incidence, from both sides where it transmits. The uniform numbers are
/// quasi-random ([`quasi_draws`]): 16,000 of them resolve the mean to about 0.2 % (against
/// 256,000 independent ones), where as many independent ones leave ±0.4 % (one standard error)
/// on glass seen from inside, whose albedo is 0.996 there.
#[test]
fn gpu_white_furnace_keeps_the_energy() {
    let Some(f) = fixture() else { return };
    let start = Instant::now();
    const N: usize = 16_000;
    let ns = V3::new(0.0, 0.0, 1.0);
    let mut inputs = Vec::new();
    let mut cases = Vec::new();
    for &name in FURNACE {
        let (material, m) = f.material(name);
        assert_eq!(m.color, [1.0; 3], "{name} is white");
        let fronts: &[bool] = if transmits(&m) { &[true, false] } else { &[true] };
        for cos in [0.9f32, 0.5, 0.2] {
            for &front in fronts {
                let p = ProbePoint { material, wo: around(ns, cos, 0.0), ns, front };
                inputs.extend(quasi_draws(p, N, cases.len() as u32 + 1000));
                // What a transmitted weight is multiplied by to undo the radiance's 1/η² (which a
                // pbr material's glass does not apply: `bsdf::glass_sample`).
                let eta = if m.kind() == MaterialKind::Pbr {
                    1.0
                } else if front {
                    m.ior
                } else {
                    1.0 / m.ior
                };
                cases.push((name, cos, front, eta));
            }
        }
    }
    let gpu = f.sample(&inputs);
    let mut failed = Vec::new();
    for (k, chunk) in gpu.chunks(N).enumerate() {
        let (name, cos, front, eta) = cases[k];
        // Absorbed draws (none valid) count as weight 0.
        let w = |s: &ProbeSample| {
            if !s.valid {
                0.0
            } else if s.through {
                s.weight.x * eta * eta
            } else {
                s.weight.x
            }
        };
        let mean = chunk.iter().map(|s| w(s) as f64).sum::<f64>() / N as f64;
        eprintln!("furnace {name:>20} cos {cos} front {front:>5}: {mean:.4}");
        if (mean - 1.0).abs() >= 0.01 {
            failed.push(format!("{name} cos {cos} front {front}: {mean}"));
        }
    }
    eprintln!("furnace: {} cases of {N} samples, {:.1} s", cases.len(), start.elapsed().as_secs_f64());
    assert!(failed.is_empty(), "the furnace loses or gains energy: {failed:?}");
}

/// χ² on the device (Mitsuba's and pbrt's test, `chi2_sphere`): the directions the device's
/// `bsdf_sample` chooses for [`CHI2`]'s cases against the device's own density of them
/// (`bsdf_eval`'s above the surface, the rough dielectric lobe's transmission below),
/// evaluated over the test's grid of directions in one dispatch.
#[test]
fn gpu_sampling_matches_the_gpu_density_chi2() {
    let Some(f) = fixture() else { return };
    let start = Instant::now();
    const N: usize = 100_000;
    let grid = chi2_directions();
    let ns = V3::new(0.0, 0.0, 1.0);
    let mut failed = Vec::new();
    for (k, &(name, cos, front)) in CHI2.iter().enumerate() {
        let (material, _) = f.material(name);
        let p = ProbePoint { material, wo: around(ns, cos, 0.0), ns, front };
        let t = Instant::now();
        let samples = f.sample(&draws(p, N, 2000 + k as u32));
        let sample_time = t.elapsed().as_secs_f64();
        let dirs = samples.iter().filter(|s| s.valid).map(|s| s.dir);
        let queries: Vec<(ProbePoint, V3<f32>)> = grid.iter().map(|&d| (p, d)).collect();
        let density = f.density(&queries);
        let eval_time = t.elapsed().as_secs_f64() - sample_time;
        match chi2_sphere(dirs, N, &density) {
            Ok(c) => eprintln!(
                "χ² {name:>15} cos {cos} front {front:>5}: {:.1} < {:.1} over {} dof, ∫pdf {:.4}, sampled {:.4} \
                 ({sample_time:.1} s sampling, {eval_time:.1} s evaluating)",
                c.statistic, c.limit, c.dof, c.integral, c.sampled
            ),
            Err(e) => failed.push(format!("{name} cos {cos} front {front}: {e}")),
        }
    }
    eprintln!("χ²: {} cases of {N} samples, {:.1} s", CHI2.len(), start.elapsed().as_secs_f64());
    assert!(failed.is_empty(), "{failed:#?}");
}
