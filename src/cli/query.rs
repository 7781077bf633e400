//! `strahl query`: the nearest surface point of each point of a CSV file (distance, foot,
//! normal, object, primitive), like `strahl trace` for rays; or with `--grid N` a distance
//! grid over the scene's bounds, written as a `.npy` array. On the CPU, in f32 (the mirror of
//! the GPU's arithmetic) or f64 (the oracle); signs by the generalized winding number
//! (`strahl_core::proximity`).

use super::trace::Precision;
use anyhow::{Result, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;
use strahl_core::accel::Bvh;
use strahl_core::math::{Real, V3};
use strahl_core::primitives::Primitives;
use strahl_core::proximity::winding::{WindingTree, inside};
use strahl_core::proximity::{Closest, closest};
use strahl_core::query::{CLOSEST_HEADER, read_points};
use strahl_core::scene::Scene;

/// Largest grid side: 1024³ points are 4 GiB of f32.
pub const MAX_GRID: u32 = 1024;

#[derive(Args, Debug)]
pub struct QueryArgs {
    /// Scene file (TOML, glTF or OBJ).
    pub scene: PathBuf,
    /// Points CSV: header x,y,z.
    #[arg(long, required_unless_present = "grid", conflicts_with = "grid")]
    pub points: Option<PathBuf>,
    /// Instead of points: an N×N×N grid over the scene's bounds (grown by 5 % of their
    /// diagonal on each side), written to -o FILE.npy as float32 of shape (N, N, N), indexed
    /// [z, y, x].
    #[arg(long, value_name = "N")]
    pub grid: Option<u32>,
    /// Distances negative inside the scene, by the generalized winding number of its meshes
    /// (and the spheres' and closed cylinders' own inside tests).
    #[arg(long)]
    pub signed: bool,
    /// Output: CSV for --points (default: standard output), .npy for --grid (required).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Arithmetic: f32 (the GPU's, mirrored on the CPU) or f64 (the oracle).
    #[arg(long, value_enum, default_value = "f32")]
    pub precision: Precision,
}

/// The scene's primitives, tree and (for signs) winding data in one precision.
struct Engine<R> {
    prims: Primitives<R>,
    bvh: Bvh,
    tree: Option<WindingTree<R>>,
}

impl<R: Real> Engine<R> {
    fn new(scene: &Scene, signed: bool) -> Self {
        let prims = Primitives::<R>::from_scene(scene);
        let bvh = Bvh::build(&prims);
        let tree = signed.then(|| WindingTree::build(&bvh, &prims));
        Self { prims, bvh, tree }
    }

    /// The nearest point and the distance to it (negative inside, where signed).
    fn query(&self, p: V3<f64>) -> Option<(Closest<R>, f64)> {
        let p = p.cast::<R>();
        let c = closest(&self.bvh, &self.prims, p)?;
        let d = c.distance().to_f64();
        let inside = self.tree.as_ref().is_some_and(|t| inside(&self.bvh, t, &self.prims, p).inside());
        Some((c, if inside { -d } else { d }))
    }

    fn csv(&self, points: &[V3<f64>]) -> String {
        let rows: Vec<String> = points
            .par_iter()
            .enumerate()
            .map(|(i, &p)| match self.query(p) {
                None => format!("{i},,,,,,,,-1,\n"),
                Some((c, d)) => {
                    let (f, n) = (c.foot.point, self.prims.foot_normal(c.prim_ref, &c.foot));
                    let tag = self.prims.tag(c.prim_ref);
                    format!("{i},{d},{},{},{},{},{},{},{},{}\n", f.x, f.y, f.z, n.x, n.y, n.z, tag.object, tag.face)
                }
            })
            .collect();
        let mut out = String::with_capacity(rows.iter().map(String::len).sum::<usize>() + CLOSEST_HEADER.len() + 1);
        let _ = writeln!(out, "{CLOSEST_HEADER}");
        rows.iter().for_each(|r| out.push_str(r));
        out
    }

    /// The grid's values, a z-slice per task, with a progress bar on a terminal.
    fn grid(&self, n: usize, lo: V3<f64>, step: V3<f64>) -> Vec<f32> {
        let bar = if std::io::stderr().is_terminal() {
            let bar = ProgressBar::with_draw_target(Some((n * n * n) as u64), ProgressDrawTarget::stderr());
            bar.set_style(
                ProgressStyle::with_template("grid [{bar:30}] {pos}/{len} points, {eta} left")
                    .expect("static template")
                    .progress_chars("=> "),
            );
            Some(bar)
        } else {
            None
        };
        let done = AtomicU64::new(0);
        let mut out = vec![0.0f32; n * n * n];
        out.par_chunks_mut(n * n).enumerate().for_each(|(k, slice)| {
            for j in 0..n {
                for i in 0..n {
                    let p = lo + V3::new(i as f64 * step.x, j as f64 * step.y, k as f64 * step.z);
                    slice[j * n + i] = self.query(p).map_or(f32::INFINITY, |(_, d)| d as f32);
                }
            }
            let total = done.fetch_add((n * n) as u64, Ordering::Relaxed) + (n * n) as u64;
            if let Some(b) = &bar {
                b.set_position(total);
            }
        });
        if let Some(b) = bar {
            b.finish_and_clear();
        }
        out
    }
}

pub fn run(a: QueryArgs) -> Result<()> {
    if let Some(n) = a.grid {
        if !(2..=MAX_GRID).contains(&n) {
            return Err(super::usage_error(format!("--grid {n}: the grid's side must be 2 to {MAX_GRID}")));
        }
        match &a.output {
            Some(p) if p.extension().is_some_and(|e| e.eq_ignore_ascii_case("npy")) => {}
            _ => return Err(super::usage_error("--grid writes a .npy array: give -o FILE.npy")),
        }
        let bytes = 4 * (n as u64).pow(3);
        if let Some(avail) = strahl_core::render::available_memory()
            && bytes > avail
        {
            bail!("--grid {n}: the grid takes {bytes} bytes, more than the {avail} bytes of memory available");
        }
    }
    if let Some(path) = &a.output {
        strahl_core::output::check_file_target(path)?;
    }
    let scene = strahl_core::scene::procedural::scene_or_obj(&a.scene)?;
    super::print_scene_warnings(&scene);
    strahl_core::render::check_memory(&scene, strahl_core::render::available_memory())?;
    match a.precision {
        Precision::F32 => run_in(&Engine::<f32>::new(&scene, a.signed), &a),
        Precision::F64 => run_in(&Engine::<f64>::new(&scene, a.signed), &a),
    }
}

fn run_in<R: Real>(engine: &Engine<R>, a: &QueryArgs) -> Result<()> {
    let start = Instant::now();
    if let Some(n) = a.grid {
        let prims = &engine.prims;
        let (mut lo, mut hi) = (V3::splat(f64::INFINITY), V3::splat(f64::NEG_INFINITY));
        for r in prims.bounded_refs() {
            let (l, h) = prims.bounds_f64(r);
            (lo, hi) = (lo.min_elem(l), hi.max_elem(h));
        }
        if prims.bounded_count() == 0 {
            bail!("{}: the scene has no bounded geometry to lay a grid over", a.scene.display());
        }
        let margin = (hi - lo).length() * 0.05;
        let (lo, hi) = (lo - V3::splat(margin), hi + V3::splat(margin));
        let step = (hi - lo) / (n - 1) as f64;
        let values = engine.grid(n as usize, lo, step);
        let path = a.output.as_ref().expect("checked in run");
        strahl_core::output::write_bytes_atomic(path, &npy_f32(&values, n as usize))?;
        eprintln!(
            "{} {n}^3 grid ({} s) over ({}, {}, {}) to ({}, {}, {}), spacing ({}, {}, {}); wrote {}",
            if a.signed { "signed-distance" } else { "distance" },
            fmt_secs(start),
            lo.x,
            lo.y,
            lo.z,
            hi.x,
            hi.y,
            hi.z,
            step.x,
            step.y,
            step.z,
            path.display()
        );
        return Ok(());
    }
    let points = read_points(a.points.as_ref().expect("clap requires --points or --grid"))?;
    let csv = engine.csv(&points);
    match &a.output {
        Some(path) => {
            strahl_core::output::write_bytes_atomic(path, csv.as_bytes())?;
            eprintln!("answered {} points in {} s; wrote {}", points.len(), fmt_secs(start), path.display());
        }
        None => std::io::stdout().write_all(csv.as_bytes())?,
    }
    Ok(())
}

fn fmt_secs(start: Instant) -> String {
    format!("{:.3}", start.elapsed().as_secs_f64())
}

/// A float32 array of shape (n, n, n) in numpy's `.npy` format, version 1.0: the magic, the
/// header's length, a Python-literal header padded with spaces to a multiple of 64 bytes and
/// ended by a newline, then the values little-endian in C order.
pub fn npy_f32(values: &[f32], n: usize) -> Vec<u8> {
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({n}, {n}, {n}), }}");
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat(unpadded.next_multiple_of(64) - unpadded));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + 4 * values.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}
