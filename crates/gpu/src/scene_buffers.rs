//! A scene's storage buffers on the device (bind group 0): uploaded once, each array checked
//! against the adapter's limits before anything is allocated and split across bindings where
//! it exceeds one ([`crate::split`]), with the bind groups each variant needs; and the frame
//! staged for each dispatch.

use crate::split::{self, Split, SplitArray};
use crate::{CachedPipeline, FeatureKey, GpuContext, GpuError, SceneBindings, objects};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use strahl_core::accel::gpu_bvh::MAX_PRIMS;
use strahl_core::layout::{FlatScene, FrameParams};

/// Bindings of group 0 (`shaders/modules/bindings.wgsl`): the frame, the packed objects
/// ([`objects`]), the triangles, BVH nodes and leaf triangles, the texels and the triangle
/// attributes; a scene whose arrays are split across several bindings has
/// [`Split::extra_bindings`] more. A variant declares those its features use.
pub const SCENE_BINDINGS: u32 = 7;

/// A scene's storage buffers on the device (bind group 0, without the frame's contents, which
/// change per dispatch). Cloning shares the buffers.
#[derive(Clone)]
pub struct SceneBuffers {
    /// The scene's features and the split of its arrays ([`split`]): the variants it runs
    /// with contain the former and equal the latter ([`SceneBuffers::runs_with`]).
    pub key: FeatureKey,
    pub frame: wgpu::Buffer,
    /// Every buffer of group 0 by its binding: the frame, each array (or part of one).
    buffers: Arc<[(u32, wgpu::Buffer)]>,
    /// Bind groups over `buffers`, one per set of bindings a variant declares.
    bind_groups: Arc<Mutex<HashMap<SceneBindings, wgpu::BindGroup>>>,
    /// Bytes uploaded.
    pub bytes: u64,
    has_bvh: bool,
}

impl SceneBuffers {
    /// Uploads `g`, each array into one storage buffer, or where it exceeds one binding into
    /// parts ([`Split::plan`]). Every size is checked before the first buffer is made, so that
    /// a scene too large for the adapter's limits allocates nothing on the device.
    pub fn upload(ctx: &GpuContext, g: &FlatScene) -> Result<Self, GpuError> {
        if g.bounded_count() > MAX_PRIMS {
            return Err(GpuError::TooManyPrimitives { count: g.bounded_count(), limit: MAX_PRIMS });
        }
        // The only other collapse failure (accel::gpu_bvh::CollapseError): a tree deeper than
        // the shaders' traversal stack, which the build rules out.
        if g.nodes.is_empty() && g.bounded_count() > FeatureKey::BRUTE_FORCE_MAX {
            return Err(GpuError::TooDeep { limit: strahl_core::accel::gpu_bvh::MAX_DEPTH });
        }
        // Sizes first: nothing is packed or allocated for a scene over the limits.
        const OBJECTS: &str =
            "the scene's objects (spheres, cylinders, planes, materials, lights, emitters, texture table, environment)";
        const TEXELS: &str = "texels (every image of the scene: textures and environment map, with its distribution)";
        ctx.check_binding_size(OBJECTS, objects::objects_bytes(g))?;
        ctx.check_binding_size(TEXELS, objects::texels_bytes(g))?;
        let split = Split::plan(
            &ctx.limits,
            [
                std::mem::size_of_val(g.triangles.as_slice()),
                std::mem::size_of_val(g.nodes.as_slice()),
                std::mem::size_of_val(g.leaf_triangles.as_slice()),
            ]
            .map(|b| b as u64),
        )?;
        ctx.check_binding_size("triangle attributes", std::mem::size_of_val(g.triangle_attrs.as_slice()) as u64)?;
        let objects = objects::pack_objects(g);
        let texels = objects::pack_texels(g);
        // In binding order, from 1 (0 is the frame).
        let arrays = [
            pod_array(OBJECTS, &objects),
            split_array(SplitArray::Triangles, &g.triangles),
            split_array(SplitArray::Nodes, &g.nodes),
            split_array(SplitArray::LeafTriangles, &g.leaf_triangles),
            pod_array(TEXELS, &texels),
            pod_array("triangle attributes", &g.triangle_attrs),
        ];
        debug_assert_eq!(arrays.len() as u32 + 1, SCENE_BINDINGS);
        ctx.scoped("uploading the scene", || Self::create(ctx, g, &arrays, split))
    }

    /// The buffers and bind group of [`SceneBuffers::upload`], whose sizes it checked.
    fn create(ctx: &GpuContext, g: &FlatScene, arrays: &[PodArray], split: Split) -> Self {
        let frame = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame"),
            size: std::mem::size_of::<FrameParams>() as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        // (binding, buffer): every array's first part (or whole) at its binding, later parts
        // at theirs.
        let mut buffers = vec![(0, frame.clone())];
        for (i, a) in arrays.iter().enumerate() {
            let binding = i as u32 + 1;
            let Some(array) = a.split else {
                buffers.push((binding, ctx.storage_bytes(a.what, a.bytes, a.element)));
                continue;
            };
            for (p, part) in split.cut(array, a.bytes).into_iter().enumerate() {
                let binding = if p == 0 { binding } else { split::extra_binding(array, p as u32) };
                buffers.push((binding, ctx.storage_bytes(a.what, part, a.element)));
            }
        }
        Self {
            key: FeatureKey::for_scene(g) | split.key(),
            frame,
            bytes: buffers[1..].iter().map(|(_, b)| b.size()).sum(),
            buffers: buffers.into(),
            bind_groups: Arc::default(),
            has_bvh: !g.nodes.is_empty(),
        }
    }

    /// The scene's bind group (group 0) for `pipeline`: the buffers at the bindings its variant
    /// declares, made once per set of bindings. A variant that [`SceneBuffers::runs_with`] this
    /// scene declares only bindings the scene has; a binding it lacks would make wgpu report a
    /// validation error, returned by the next [`GpuContext::scoped`] or [`GpuContext::check`].
    pub fn bind_group(&self, ctx: &GpuContext, pipeline: &CachedPipeline) -> wgpu::BindGroup {
        let bindings = &pipeline.scene_bindings;
        let mut groups = self.bind_groups.lock().expect("scene bind group lock");
        let group = groups.entry(bindings.clone()).or_insert_with(|| {
            let entries: Vec<_> = self
                .buffers
                .iter()
                .filter(|(b, _)| bindings.contains(b))
                .map(|(binding, buffer)| wgpu::BindGroupEntry {
                    binding: *binding,
                    resource: buffer.as_entire_binding(),
                })
                .collect();
            ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("scene"),
                layout: &ctx.scene_layout(bindings),
                entries: &entries,
            })
        });
        group.clone()
    }

    /// How the scene's large arrays are split across bindings.
    pub fn split(&self) -> Split {
        Split::of_key(self.key)
    }

    /// Storage buffers group 0 binds for this scene.
    pub fn bindings(&self) -> u32 {
        SCENE_BINDINGS + self.split().extra_bindings()
    }

    /// Whether a variant compiled with `key` can run on this scene: it must contain every
    /// feature the scene uses, read the scene's arrays split as they are, and walk a BVH only
    /// if the scene has one.
    pub fn runs_with(&self, key: FeatureKey) -> bool {
        key.flags().contains(self.key.flags())
            && Split::of_key(key) == self.split()
            && (!key.contains(FeatureKey::BVH) || self.has_bvh)
    }
}

/// One scene array as bytes, named for errors, with its element size, and which it is where
/// it may be split across bindings.
struct PodArray<'a> {
    what: &'static str,
    bytes: &'a [u8],
    element: usize,
    split: Option<SplitArray>,
}

fn pod_array<'a, T: bytemuck::Pod>(what: &'static str, data: &'a [T]) -> PodArray<'a> {
    PodArray { what, bytes: bytemuck::cast_slice(data), element: std::mem::size_of::<T>(), split: None }
}

fn split_array<T: bytemuck::Pod>(array: SplitArray, data: &[T]) -> PodArray<'_> {
    debug_assert_eq!(std::mem::size_of::<T>() as u64, array.element_bytes());
    PodArray { split: Some(array), ..pod_array(array.what(), data) }
}

/// Records into `enc` a copy of `frame` into the scene's frame buffer, so that the dispatches
/// recorded after it (until the next such copy) read it: each tile or pass needs its own frame,
/// in command order (a queue write would land before the whole submission).
pub fn stage_frame(ctx: &GpuContext, enc: &mut wgpu::CommandEncoder, scene: &SceneBuffers, frame: &FrameParams) {
    let staging = wgpu::util::DeviceExt::create_buffer_init(
        &ctx.device,
        &wgpu::util::BufferInitDescriptor {
            label: Some("frame"),
            contents: bytemuck::bytes_of(frame),
            usage: wgpu::BufferUsages::COPY_SRC,
        },
    );
    enc.copy_buffer_to_buffer(&staging, 0, &scene.frame, 0, std::mem::size_of::<FrameParams>() as u64);
}
