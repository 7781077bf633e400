//! The `strahl` command line's own parts: error against wall time ([`converge`]) and the
//! numerical-stability suite ([`stiff`]). The rest lives in the workspace's crates:
//! `strahl-core` (scenes, BVH, render stages, the CPU backend), `strahl-gpu` (the WGSL
//! backend), `strahl-metrics` (image comparison) and `strahl-viewer` (`strahl view`).

// `!(x >= 0.0)` is used on purpose throughout: unlike `x < 0.0` it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod converge;
pub mod stiff;
