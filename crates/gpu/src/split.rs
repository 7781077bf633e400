//! Scene arrays larger than one storage binding, split across several.
//!
//! An adapter caps what one storage-buffer binding may hold (`max_storage_buffer_binding_size`,
//! and every buffer at `max_buffer_size`; lavapipe: 128 MiB). Three arrays grow with the
//! triangle count: the scene-order triangles (48 bytes each), the BVH's nodes (64 bytes, about
//! 0.55 per triangle) and its leaf-order triangles (48 bytes); the first two pass 128 MiB near
//! 2.8M triangles. A scene whose array is over the limit gets that array cut into parts of
//! [`Split::per_part`] elements, each part its own buffer bound at its own binding (part 0 at
//! the array's usual binding, the others at [`extra_binding`]), and the shaders compiled for
//! it read element i in part i / per_part at i % per_part (`fetch_node`, `fetch_leaf_triangle`
//! and `scene_triangle` in `shaders/modules/traverse.wgsl`).
//!
//! The split is part of the scene's [`FeatureKey`] (the shader defs `TRIANGLE_PARTS`,
//! `NODE_PARTS`, `LEAF_TRIANGLE_PARTS` and the `*_PER_PART` counts), so a scene whose arrays
//! fit one binding each runs the shaders it ran before, with none of the part selection.
//!
//! How far it reaches: [`MAX_PARTS`] parts per array (lavapipe: 4 × 128 MiB, 11.1M
//! triangles), and the extra bindings must fit the adapter's `max_storage_buffers_per_shader_stage`
//! beside the programs' own (lavapipe: 32 with Mesa 22.3, 48 with Mesa 25). [`Split::plan`]
//! fails before anything is allocated where a scene needs more.

use super::{FeatureKey, GpuError, SCENE_BINDINGS};
use strahl_core::accel::gpu_bvh::{GpuLeafTriangle, GpuNode};
use strahl_core::layout::FlatTriangle;

/// Bits of the key for one array's part count minus one.
const PART_BITS: u32 = 2;
/// The most parts one array is split into: the bindings `shaders/modules/bindings.wgsl`
/// declares for it.
pub const MAX_PARTS: u32 = 1 << PART_BITS;
/// Bits of the key for log2 of a part's bytes (0: nothing is split).
const LOG2_BITS: u32 = 5;
/// Where the split sits in a [`FeatureKey`]: above its flags.
const SHIFT: u32 = FeatureKey::FLAG_COUNT;
const LOG2_SHIFT: u32 = SHIFT + SplitArray::ALL.len() as u32 * PART_BITS;
/// The bits of a [`FeatureKey`] that hold its split.
pub const MASK: u32 = ((1 << (SplitArray::ALL.len() as u32 * PART_BITS + LOG2_BITS)) - 1) << SHIFT;

/// An array that may be split, in the order of the key's fields.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplitArray {
    /// `triangles` (scene order): read by index for hits' tags, emitters and textures.
    Triangles,
    /// `nodes`: the BVH's inner nodes.
    Nodes,
    /// `leaf_triangles`: the triangles in the BVH's leaf order.
    LeafTriangles,
}

impl SplitArray {
    pub const ALL: [SplitArray; 3] = [SplitArray::Triangles, SplitArray::Nodes, SplitArray::LeafTriangles];

    /// The array's name in errors (as [`super::SceneBuffers::upload`] names it).
    pub fn what(self) -> &'static str {
        match self {
            SplitArray::Triangles => "triangles",
            SplitArray::Nodes => "BVH nodes",
            SplitArray::LeafTriangles => "leaf-order triangles",
        }
    }

    /// Bytes of one element.
    pub fn element_bytes(self) -> u64 {
        (match self {
            SplitArray::Triangles => size_of::<FlatTriangle>(),
            SplitArray::Nodes => size_of::<GpuNode>(),
            SplitArray::LeafTriangles => size_of::<GpuLeafTriangle>(),
        }) as u64
    }

    /// The shader defs of its part count and of the elements per part.
    pub fn defs(self) -> (&'static str, &'static str) {
        match self {
            SplitArray::Triangles => ("TRIANGLE_PARTS", "TRIANGLES_PER_PART"),
            SplitArray::Nodes => ("NODE_PARTS", "NODES_PER_PART"),
            SplitArray::LeafTriangles => ("LEAF_TRIANGLE_PARTS", "LEAF_TRIANGLES_PER_PART"),
        }
    }

    fn index(self) -> usize {
        self as usize
    }
}

/// The binding of part `part` (1 ..= [`MAX_PARTS`] - 1) of `array` in group 0: after the
/// scene's [`SCENE_BINDINGS`], [`MAX_PARTS`] - 1 per array (as `shaders/modules/bindings.wgsl`
/// declares them). Part 0 keeps the array's usual binding.
pub fn extra_binding(array: SplitArray, part: u32) -> u32 {
    debug_assert!((1..MAX_PARTS).contains(&part));
    SCENE_BINDINGS + array.index() as u32 * (MAX_PARTS - 1) + part - 1
}

/// How a scene's large arrays are split: parts per array, each part (but the last) of
/// [`Split::per_part`] elements. [`Split::NONE`] splits nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Split {
    parts: [u32; 3],
    /// log2 of the bytes a part may hold; 0 when nothing is split.
    part_log2: u32,
}

impl Default for Split {
    fn default() -> Self {
        Self::NONE
    }
}

impl Split {
    pub const NONE: Split = Split { parts: [1; 3], part_log2: 0 };

    /// How arrays of `bytes` bytes (in [`SplitArray::ALL`] order) are split on an adapter with
    /// `limits`: not at all where each fits one binding; else every array over the limit into
    /// parts of the largest power of two of bytes a binding holds (whole elements). Fails,
    /// naming the array, its size and the limit, where an array needs more than
    /// [`MAX_PARTS`] parts or the parts more bindings than the adapter allows.
    pub fn plan(limits: &wgpu::Limits, bytes: [u64; 3]) -> Result<Split, GpuError> {
        let (limit, limit_name) = binding_limit(limits);
        if bytes.iter().all(|&b| b <= limit) {
            return Ok(Split::NONE);
        }
        // A power of two, so that the key holds it in a few bits; at least half the limit.
        let part_log2 = (63 - limit.leading_zeros()).min((1 << LOG2_BITS) - 1);
        let mut split = Split { parts: [1; 3], part_log2 };
        for (array, &need) in SplitArray::ALL.iter().zip(&bytes) {
            if need <= limit {
                continue;
            }
            let per_part = split.per_part(*array) as u64;
            if per_part == 0 {
                return Err(GpuError::TooLarge { what: array.what().to_string(), need, limit, limit_name });
            }
            let parts = (need / array.element_bytes()).div_ceil(per_part);
            if parts > MAX_PARTS as u64 {
                return Err(GpuError::TooManyParts {
                    what: array.what(),
                    need,
                    parts,
                    part_bytes: per_part * array.element_bytes(),
                    max_parts: MAX_PARTS,
                    limit_name,
                });
            }
            split.parts[array.index()] = parts as u32;
        }
        let need = crate::MIN_STORAGE_BUFFERS + split.extra_bindings();
        if need > limits.max_storage_buffers_per_shader_stage {
            return Err(GpuError::TooManyBindings {
                need,
                extra: split.extra_bindings(),
                limit: limits.max_storage_buffers_per_shader_stage,
            });
        }
        Ok(split)
    }

    /// Whether any array is split.
    pub fn is_split(self) -> bool {
        self.part_log2 != 0
    }

    /// Parts of `array` (1: whole).
    pub fn parts(self, array: SplitArray) -> u32 {
        self.parts[array.index()]
    }

    /// Elements in every part of a split array but the last; 0 when nothing is split.
    pub fn per_part(self, array: SplitArray) -> u32 {
        if !self.is_split() {
            return 0;
        }
        ((1u64 << self.part_log2) / array.element_bytes()) as u32
    }

    /// Bindings beyond the scene's [`SCENE_BINDINGS`]: one per part after the first.
    pub fn extra_bindings(self) -> u32 {
        self.parts.iter().map(|p| p - 1).sum()
    }

    /// `bytes`, the whole array `array`, cut into its parts.
    pub fn cut(self, array: SplitArray, bytes: &[u8]) -> Vec<&[u8]> {
        if self.parts(array) == 1 {
            return vec![bytes];
        }
        let part_bytes = self.per_part(array) as usize * array.element_bytes() as usize;
        bytes.chunks(part_bytes).collect()
    }

    /// The split as a [`FeatureKey`] without flags (its bits within [`MASK`]).
    pub fn key(self) -> FeatureKey {
        if !self.is_split() {
            return FeatureKey::empty();
        }
        let parts =
            SplitArray::ALL.iter().map(|a| (self.parts(*a) - 1) << (SHIFT + a.index() as u32 * PART_BITS)).sum::<u32>();
        FeatureKey::from_bits_retain(parts | self.part_log2 << LOG2_SHIFT)
    }

    /// The split a key's bits hold.
    pub fn of_key(key: FeatureKey) -> Split {
        let bits = key.bits();
        let part_log2 = (bits >> LOG2_SHIFT) & ((1 << LOG2_BITS) - 1);
        if part_log2 == 0 {
            return Split::NONE;
        }
        let field = |a: SplitArray| ((bits >> (SHIFT + a.index() as u32 * PART_BITS)) & (MAX_PARTS - 1)) + 1;
        Split { parts: SplitArray::ALL.map(field), part_log2 }
    }

    /// A split with the given parts per array (in [`SplitArray::ALL`] order, each 1 ..=
    /// [`MAX_PARTS`]) of 2^`part_log2` bytes: for tests and for checking every variant.
    pub fn with_parts(parts: [u32; 3], part_log2: u32) -> Split {
        assert!(parts.iter().all(|p| (1..=MAX_PARTS).contains(p)) && (1..1 << LOG2_BITS).contains(&part_log2));
        Split { parts, part_log2 }
    }

    /// "TRIANGLE_PARTS=2+NODE_PARTS=2+LEAF_TRIANGLE_PARTS=2 of 134217728 bytes", or "" for
    /// [`Split::NONE`].
    pub fn label(self) -> String {
        if !self.is_split() {
            return String::new();
        }
        let parts: Vec<String> = SplitArray::ALL.iter().map(|a| format!("{}={}", a.defs().0, self.parts(*a))).collect();
        format!("{} of {} bytes", parts.join("+"), 1u64 << self.part_log2)
    }
}

/// The most bytes one storage binding may hold on an adapter with `limits`, and the limit's
/// name: `max_storage_buffer_binding_size`, or `max_buffer_size` where that is smaller.
pub fn binding_limit(limits: &wgpu::Limits) -> (u64, &'static str) {
    if limits.max_buffer_size < limits.max_storage_buffer_binding_size {
        (limits.max_buffer_size, "max_buffer_size")
    } else {
        (limits.max_storage_buffer_binding_size, "max_storage_buffer_binding_size")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// lavapipe's limits: 128 MiB per binding, 2 GiB per buffer, `stage` storage buffers.
    fn lavapipe(stage: u32) -> wgpu::Limits {
        wgpu::Limits {
            max_storage_buffer_binding_size: 128 << 20,
            max_buffer_size: (1 << 31) - 1,
            max_storage_buffers_per_shader_stage: stage,
            ..wgpu::Limits::default()
        }
    }

    /// The bytes of the three arrays for `n` triangles (0.55 nodes per triangle).
    fn torus_bytes(n: u64) -> [u64; 3] {
        [48 * n, 64 * (n * 55 / 100), 48 * n]
    }

    #[test]
    fn arrays_that_fit_are_not_split() {
        let s = Split::plan(&lavapipe(32), torus_bytes(2_500_000)).unwrap();
        assert_eq!(s, Split::NONE);
        assert_eq!((s.key(), s.extra_bindings(), s.label()), (FeatureKey::empty(), 0, String::new()));
        assert_eq!(Split::of_key(FeatureKey::ALL), Split::NONE);
    }

    #[test]
    fn five_million_triangles_split_in_two_parts_per_array() {
        let s = Split::plan(&lavapipe(32), torus_bytes(5_000_000)).unwrap();
        assert_eq!(SplitArray::ALL.map(|a| s.parts(a)), [2, 2, 2]);
        assert_eq!(s.per_part(SplitArray::Triangles), (128 << 20) / 48);
        assert_eq!(s.per_part(SplitArray::Nodes), 1 << 21);
        assert_eq!(s.extra_bindings(), 3);
        // The key holds the split above the flags, and gives it back.
        let key = FeatureKey::ALL | s.key();
        assert_eq!(s.key().bits() & !MASK, 0);
        assert_eq!(key.flags(), FeatureKey::ALL);
        assert_eq!(Split::of_key(key), s);
        assert_eq!(s.label(), "TRIANGLE_PARTS=2+NODE_PARTS=2+LEAF_TRIANGLE_PARTS=2 of 134217728 bytes");
    }

    #[test]
    fn parts_hold_whole_elements_and_cut_the_array_in_order() {
        // 1000 bytes per binding: parts of 512 bytes, 10 triangles of 48 bytes (480 bytes).
        let limits = wgpu::Limits { max_storage_buffer_binding_size: 1000, ..lavapipe(32) };
        let s = Split::plan(&limits, [48 * 25, 64 * 3, 48 * 21]).unwrap();
        assert_eq!(SplitArray::ALL.map(|a| s.parts(a)), [3, 1, 3]);
        let bytes: Vec<u8> = (0..48 * 25).map(|i| i as u8).collect();
        let parts = s.cut(SplitArray::Triangles, &bytes);
        assert_eq!(parts.iter().map(|p| p.len()).collect::<Vec<_>>(), [480, 480, 240]);
        assert_eq!(parts.concat(), bytes);
        assert_eq!(s.cut(SplitArray::Nodes, &bytes[..192]), [&bytes[..192]]);
    }

    #[test]
    fn max_buffer_size_bounds_a_part_when_it_is_the_smaller_limit() {
        let limits = wgpu::Limits { max_buffer_size: 100 << 20, ..lavapipe(32) };
        assert_eq!(binding_limit(&limits), (100 << 20, "max_buffer_size"));
        let s = Split::plan(&limits, torus_bytes(2_500_000)).unwrap();
        // Parts of 64 MiB: 120 MB of triangles in two; 88 MB of nodes fit one binding.
        assert_eq!(s.per_part(SplitArray::Nodes), 1 << 20);
        assert_eq!(SplitArray::ALL.map(|a| s.parts(a)), [2, 1, 2]);
    }

    #[test]
    fn too_many_parts_and_too_few_bindings_are_refused_naming_the_limit() {
        // 12M triangles: 576 MB, five parts of 128 MiB.
        let e = Split::plan(&lavapipe(48), torus_bytes(12_000_000)).unwrap_err();
        let msg = e.to_string();
        assert!(matches!(e, GpuError::TooManyParts { parts: 5, .. }), "{e}");
        for part in
            ["triangles", "576000000", "5 storage bindings", "134217696", "max_storage_buffer_binding_size", "the 4"]
        {
            assert!(msg.contains(part), "{part} missing from: {msg}");
        }
        // 5M triangles need 3 more bindings: 8 + 3 exceed 10.
        let e = Split::plan(&lavapipe(10), torus_bytes(5_000_000)).unwrap_err();
        let msg = e.to_string();
        assert!(matches!(e, GpuError::TooManyBindings { need: 11, extra: 3, limit: 10 }), "{e}");
        assert!(
            msg.contains("11") && msg.contains("10") && msg.contains("max_storage_buffers_per_shader_stage"),
            "{msg}"
        );
        // A binding smaller than one element holds no part.
        let tiny = wgpu::Limits { max_storage_buffer_binding_size: 40, ..lavapipe(48) };
        assert!(matches!(Split::plan(&tiny, [480, 0, 0]), Err(GpuError::TooLarge { need: 480, limit: 40, .. })));
    }

    #[test]
    fn every_split_a_key_can_hold_comes_back_from_it() {
        for t in 1..=MAX_PARTS {
            for n in 1..=MAX_PARTS {
                for l in 1..=MAX_PARTS {
                    for log2 in [5, 27, 31] {
                        let s = Split::with_parts([t, n, l], log2);
                        assert_eq!(Split::of_key(s.key() | FeatureKey::ALL), s);
                        assert_eq!(s.key().bits() & !MASK, 0);
                    }
                }
            }
        }
    }

    #[test]
    fn extra_bindings_follow_the_scene_bindings_without_overlap() {
        let all: Vec<u32> =
            SplitArray::ALL.iter().flat_map(|&a| (1..MAX_PARTS).map(move |p| extra_binding(a, p))).collect();
        let want: Vec<u32> = (SCENE_BINDINGS..SCENE_BINDINGS + 3 * (MAX_PARTS - 1)).collect();
        assert_eq!(all, want);
    }
}
