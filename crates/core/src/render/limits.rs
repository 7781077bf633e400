//! How far the tracers go, in values both backends' tracers read (`crates/gpu/src/shared.rs`
//! writes them into the WGSL): the Whitted ray stack, shadow rays' passes and reach, and where
//! Russian roulette starts.

/// Depth of the explicit ray stack. A dielectric hit pushes two rays; when the stack is full
/// its reflected ray is dropped (only scenes with more than this many nested refractions).
pub const WHITTED_STACK: usize = 16;
/// Traversals a shadow ray may make: it passes through up to `SHADOW_PASSES - 1` dielectric
/// surfaces (tinted by their colour; glass casts a coloured shadow, not a black one) and
/// counts as blocked after that.
pub const SHADOW_PASSES: u32 = 8;
/// Russian roulette may end a path once it has this many segments: Mitsuba's default
/// `rr_depth`. An earlier start saves time per sample but costs more in noise on scenes lit
/// along long caustic paths, as the seed scene's spheres inside the glass are.
pub const RR_DEPTH: u32 = 5;
/// Shadow rays stop this fraction short of the sampled light point, so the emitter's own
/// surface does not count as a blocker.
pub const SHADOW_REACH: f32 = 1.0 - 1.0 / 4096.0;
