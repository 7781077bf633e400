// Wavefront path tracing (Laine, Karras & Aila, "Megakernels Considered Harmful", HPG 2013):
// one sample pass of a band of pixels as separate kernels over queues of paths, so that each
// kernel's invocations all do the same work. Per pass: wf_generate starts a path per pixel; then
// per segment wf_extend finds each queued path's nearest hit, wf_shade shades it
// (strahl::path, as the megakernel.wgsl does) and queues the path again if it goes
// on and its area-light shadow ray if it has one, wf_args sizes the next dispatches (indirect),
// wf_shadow traces the shadow rays (first hit only); wf_finish adds each path's radiance to its
// pixel. The host side is crates/gpu/src/wavefront.rs; what a path computes is the twin of
// crates/cpu/src/path.rs (radiance: the same sums in the same order).
//
// A vertex's area-light contribution waits in `pending` until its shadow ray is traced: the next
// wf_shade of the path (or wf_finish) adds it if the ray was not blocked, before anything else,
// which is where the megakernel adds it.
#import strahl::types::{FRAME_ACCUMULATE, F32_MAX}
#import strahl::bindings::frame
#import strahl::traverse::{Nearest, nearest_hit, occluded}
#import strahl::camera::output_index
#import strahl::path::{PathState, NeeRay, path_start, shade_vertex, finite_or_black}

// A path's nearest hit between wf_extend and wf_shade (traverse::Nearest, host-shareable).
struct WfHit {
    normal: vec3<f32>,
    t: f32,
    prim_ref: u32,
    part: u32,
    // 1: found, 2: kept (normal and material are set).
    flags: u32,
    material: u32,
}

// A queued shadow ray: from origin along dir up to dist, for path `path`.
struct WfShadow {
    origin: vec3<f32>,
    path: u32,
    dir: vec3<f32>,
    dist: f32,
}

@group(1) @binding(0) var<storage, read_write> paths: array<PathState>;
@group(1) @binding(1) var<storage, read_write> hits: array<WfHit>;
// Per path: the area-light contribution of its last vertex (xyz) and whether its shadow ray
// reached the light (w: 1, or 0 when blocked or when there is none).
@group(1) @binding(2) var<storage, read_write> pending: array<vec4<f32>>;
@group(1) @binding(3) var<storage, read_write> queue_in: array<u32>;
@group(1) @binding(4) var<storage, read_write> queue_out: array<u32>;
@group(1) @binding(5) var<storage, read_write> shadows: array<WfShadow>;
// Counters and indirect dispatch arguments (backend::gpu::wavefront::Counters).
@group(1) @binding(6) var<storage, read_write> counters: array<atomic<u32>>;
@group(1) @binding(7) var<storage, read_write> output: array<vec4<f32>>;

const WAVEFRONT_WORKGROUP: u32 = #{WAVEFRONT_WORKGROUP};
const WF_PATHS_IN: u32 = #{WF_PATHS_IN};
const WF_PATHS_OUT: u32 = #{WF_PATHS_OUT};
const WF_SHADOWS_OUT: u32 = #{WF_SHADOWS_OUT};
const WF_SHADOWS_IN: u32 = #{WF_SHADOWS_IN};
const WF_ARGS_PATHS: u32 = #{WF_ARGS_PATHS};
const WF_ARGS_SHADOWS: u32 = #{WF_ARGS_SHADOWS};

// Paths of the band: one per pixel of the rectangle frame.tile_origin, frame.tile_size.
fn band_paths() -> u32 {
    return frame.tile_size.x * frame.tile_size.y;
}

fn pixel_of(i: u32) -> vec2<u32> {
    return frame.tile_origin + vec2<u32>(i % frame.tile_size.x, i / frame.tile_size.x);
}

@compute @workgroup_size(WAVEFRONT_WORKGROUP, 1, 1)
fn wf_generate(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= band_paths() {
        return;
    }
    let px = pixel_of(i);
    paths[i] = path_start(px.x, px.y, frame.sample_base);
    pending[i] = vec4<f32>(0.0);
    queue_in[i] = i;
}

@compute @workgroup_size(WAVEFRONT_WORKGROUP, 1, 1)
fn wf_extend(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= atomicLoad(&counters[WF_PATHS_IN]) {
        return;
    }
    let p = queue_in[gid.x];
    let hit = nearest_hit(paths[p].o, paths[p].d, 0.0, F32_MAX);
    let flags = select(0u, 1u, hit.found) | select(0u, 2u, hit.kept);
    hits[p] = WfHit(hit.normal, hit.t, hit.prim_ref, hit.part, flags, hit.material);
}

// The pending area-light contribution of path p, if its shadow ray reached the light.
fn take_pending(p: u32) -> vec3<f32> {
    let e = pending[p];
    return select(vec3<f32>(0.0), e.xyz, e.w != 0.0);
}

@compute @workgroup_size(WAVEFRONT_WORKGROUP, 1, 1)
fn wf_shade(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= atomicLoad(&counters[WF_PATHS_IN]) {
        return;
    }
    let p = queue_in[gid.x];
    var st = paths[p];
    st.sum += take_pending(p);
    let h = hits[p];
    let hit = Nearest(h.t, h.prim_ref, h.part, (h.flags & 1u) != 0u, (h.flags & 2u) != 0u, h.normal, h.material);
    var nee: NeeRay;
    let more = shade_vertex(&st, hit, &nee);
    paths[p] = st;
    if nee.valid != 0u {
        pending[p] = vec4<f32>(nee.value, 1.0);
        let k = atomicAdd(&counters[WF_SHADOWS_OUT], 1u);
        shadows[k] = WfShadow(nee.origin, p, nee.dir, nee.dist);
    } else {
        pending[p] = vec4<f32>(0.0);
    }
    if more {
        queue_out[atomicAdd(&counters[WF_PATHS_OUT], 1u)] = p;
    }
}

// One invocation between segments: the paths queued by wf_shade become the next segment's
// input, its shadow rays the input of wf_shadow, and the indirect dispatch sizes follow.
@compute @workgroup_size(1, 1, 1)
fn wf_args() {
    let paths_next = atomicExchange(&counters[WF_PATHS_OUT], 0u);
    let shadows_next = atomicExchange(&counters[WF_SHADOWS_OUT], 0u);
    atomicStore(&counters[WF_PATHS_IN], paths_next);
    atomicStore(&counters[WF_SHADOWS_IN], shadows_next);
    atomicStore(&counters[WF_ARGS_PATHS], (paths_next + WAVEFRONT_WORKGROUP - 1u) / WAVEFRONT_WORKGROUP);
    atomicStore(&counters[WF_ARGS_SHADOWS], (shadows_next + WAVEFRONT_WORKGROUP - 1u) / WAVEFRONT_WORKGROUP);
}

@compute @workgroup_size(WAVEFRONT_WORKGROUP, 1, 1)
fn wf_shadow(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= atomicLoad(&counters[WF_SHADOWS_IN]) {
        return;
    }
    let s = shadows[gid.x];
    if occluded(s.origin, s.dir, 0.0, s.dist) {
        pending[s.path].w = 0.0;
    }
}

@compute @workgroup_size(WAVEFRONT_WORKGROUP, 1, 1)
fn wf_finish(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= band_paths() {
        return;
    }
    let c = finite_or_black(paths[i].sum + take_pending(i));
    let px = pixel_of(i);
    let o = output_index(frame, px.x, px.y);
    if (frame.flags & FRAME_ACCUMULATE) != 0u {
        output[o] += vec4<f32>(c, 0.0);
    } else {
        output[o] = vec4<f32>(c, 1.0);
    }
}
