//! A bundle's vertices as the lanes shade them: what the paths' rays met, read lane after lane
//! ([`gather`]: the hit, its material, the geometry its normal and textures come from), then
//! made into lane values ([`vertex`]: the paths' state, the hit's normal as
//! `Primitives::hit` computes it, and the surface as `surface::surface` gives it). A vertex
//! whose material the lanes do not shade is shaded by [`path::shade_vertex`] during the gather
//! and counted ([`Fallbacks`]).

// Lane loops index several arrays with the lane: the form the compiler turns into vector
// instructions.
#![allow(clippy::needless_range_loop)]

use super::facts::{Facts, Kind};
use super::paths::Paths;
use super::surface as lane_surface;
use crate::path::{self, NeeRay};
use crate::shade::ShadeInputs;
use strahl_core::layout::{ATTR_COLORS, ATTR_NORMALS};
use strahl_core::math::lanes::{F, M, U, V};
use strahl_core::primitives::{Hit, Nearest, PrimKind};

/// The paths `k .. k + n` (n ≤ N) of one bundle and what their rays met: `hits[..n]`, with
/// their hit records where the walk made them.
pub(super) struct Bundle<'a> {
    pub k: usize,
    pub n: usize,
    pub hits: &'a [Nearest<f32>],
    pub records: Option<&'a [Option<Hit<f32>>]>,
}

/// What shading a bundle gives besides the paths themselves: `more[i]` for each path `i` that
/// goes on, the area-light shadow rays with their paths' indices, and the vertices shaded one
/// path at a time.
pub(super) struct Out<'a> {
    pub more: &'a mut [bool],
    pub nee: &'a mut Vec<(u32, NeeRay)>,
    pub fallbacks: &'a mut Fallbacks,
}

/// Vertices the lanes left to the one-path code ([`path::shade_vertex`]), by why: the scene has
/// point or directional lights, a triangle has vertex colours, or the material is one the
/// lanes do not shade (counted per material index). Each gives the image it would give in
/// lanes; the count says how much of the render went the slower way.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Fallbacks {
    /// Vertices shaded in lanes.
    pub lanes: u64,
    pub delta_lights: u64,
    pub vertex_colors: u64,
    /// Per material index.
    pub materials: Vec<u64>,
}

impl Fallbacks {
    pub fn add(&mut self, o: &Fallbacks) {
        self.lanes += o.lanes;
        self.delta_lights += o.delta_lights;
        self.vertex_colors += o.vertex_colors;
        if self.materials.len() < o.materials.len() {
            self.materials.resize(o.materials.len(), 0);
        }
        for (a, b) in self.materials.iter_mut().zip(&o.materials) {
            *a += b;
        }
    }

    /// Vertices shaded one path at a time.
    pub fn total(&self) -> u64 {
        self.delta_lights + self.vertex_colors + self.materials.iter().sum::<u64>()
    }

    /// What the render's summary says where vertices were shaded one path at a time (None
    /// where none was): how many of how many, and why, naming the materials (`materials`: the
    /// scene's, in the order the flat layout keeps them).
    pub fn summary(&self, materials: &[strahl_core::scene::Material]) -> Option<String> {
        let slow = self.total();
        if slow == 0 {
            return None;
        }
        let mut why = Vec::new();
        if self.delta_lights > 0 {
            why.push(format!("{} in a scene with point or directional lights", self.delta_lights));
        }
        if self.vertex_colors > 0 {
            why.push(format!("{} on triangles with vertex colours", self.vertex_colors));
        }
        let mut by_material: Vec<(usize, u64)> =
            self.materials.iter().copied().enumerate().filter(|&(_, n)| n > 0).collect();
        by_material.sort_by_key(|&(m, n)| (std::cmp::Reverse(n), m));
        for (m, n) in by_material {
            let name = materials.get(m).map_or_else(|| format!("#{m}"), |m| format!("'{}'", m.name));
            why.push(format!("{n} of material {name}"));
        }
        let all = slow + self.lanes;
        Some(format!(
            "{slow} of {all} path vertices ({:.1} %) were shaded one path at a time, not in SIMD lanes: {}",
            100.0 * slow as f64 / all.max(1) as f64,
            why.join(", ")
        ))
    }

    fn material(&mut self, m: usize) {
        if self.materials.len() <= m {
            self.materials.resize(m + 1, 0);
        }
        self.materials[m] += 1;
    }
}

/// What the lanes read of their hits and materials, lane after lane. Lanes not `on` were
/// shaded by the one-path code (or are past the bundle's end).
pub(super) struct Gathered<const N: usize> {
    pub on: [bool; N],
    pub is_hit: [bool; N],
    pub t: [f32; N],
    /// The hit's normal where the walk's record or `Primitives::hit` gave it (`given`).
    pub nrm: [[f32; N]; 3],
    pub given: [bool; N],
    /// Geometry for the normals the lanes compute: a sphere's centre (`sphere`), else a
    /// triangle's vertices.
    pub geo: [[f32; N]; 9],
    pub sphere: [bool; N],
    pub kind: [u32; N],
    pub flags: [u32; N],
    pub emits: [bool; N],
    /// An area light that next-event estimation samples (its emission is weighed by MIS).
    pub sampled: [bool; N],
    pub color: [[f32; N]; 3],
    pub radiance: [[f32; N]; 3],
    pub ior: [f32; N],
    pub metallic: [f32; N],
    pub roughness: [f32; N],
    /// Triangles with attributes whose textures or vertex normals the lanes read: the
    /// triangle, its corners (for the barycentric weights), the textures.
    pub surf: [bool; N],
    pub smooth: [bool; N],
    pub tri: [u32; N],
    pub corners: [[f32; N]; 9],
    pub color_tex: [u32; N],
    pub mr_tex: [u32; N],
}

impl<const N: usize> Gathered<N> {
    fn new() -> Self {
        Self {
            on: [false; N],
            is_hit: [false; N],
            t: [0.0; N],
            nrm: [[0.0; N]; 3],
            given: [false; N],
            geo: [[0.0; N]; 9],
            sphere: [false; N],
            kind: [0; N],
            flags: [0; N],
            emits: [false; N],
            sampled: [false; N],
            color: [[0.0; N]; 3],
            radiance: [[0.0; N]; 3],
            ior: [1.0; N],
            metallic: [0.0; N],
            roughness: [0.0; N],
            surf: [false; N],
            smooth: [false; N],
            tri: [0; N],
            corners: [[0.0; N]; 9],
            color_tex: [0; N],
            mr_tex: [0; N],
        }
    }
}

/// Lane after lane: which lanes the loops shade, and what they read of the hit and its
/// material; the others are shaded by the one-path code now (and counted in `out`).
#[inline(always)]
pub(super) fn gather<const N: usize, const RICH: bool>(
    inp: &ShadeInputs,
    facts: &Facts,
    p: &mut Paths,
    b: &Bundle,
    out: &mut Out,
) -> Gathered<N> {
    let (g, prims) = (inp.flat, inp.prims);
    let mut s = Gathered::<N>::new();
    for l in 0..b.n {
        let i = b.k + l;
        let h = &b.hits[l];
        let prim = h.prim_ref;
        let mi = if h.found { prims.tag(prim).material as usize } else { 0 };
        let vertex_colors = h.found
            && prim.kind() == PrimKind::Triangle
            && !g.triangle_attrs.is_empty()
            && g.triangle_attrs[prim.index()].flags & ATTR_COLORS != 0;
        let lane_kind = if !facts.lanes_ok {
            out.fallbacks.delta_lights += 1;
            None
        } else if !h.found {
            Some(None)
        } else if vertex_colors {
            out.fallbacks.vertex_colors += 1;
            None
        } else if let Some(m) = facts.materials[mi] {
            Some(Some(m))
        } else {
            out.fallbacks.material(mi);
            None
        };
        let Some(lane_kind) = lane_kind else {
            let (mut st, mut rng) = p.get(i);
            let hit = match b.records {
                Some(r) => r[l],
                None => h.found.then(|| prims.hit(prim, &st.ray, h.t, h.part)),
            };
            let mut ne = None;
            out.more[i] = path::shade_vertex(inp, &mut st, hit.as_ref(), &mut rng, &mut ne);
            p.set(i, &st, &rng);
            if let Some(x) = ne {
                out.nee.push((i as u32, x));
            }
            continue;
        };
        out.fallbacks.lanes += 1;
        s.on[l] = true;
        let Some(m) = lane_kind else {
            continue;
        };
        s.is_hit[l] = true;
        s.t[l] = h.t;
        match (b.records.and_then(|r| r[l]), prim.kind()) {
            // The walk's own record (its triangle copy gave the normal).
            (Some(h), _) => {
                (s.nrm[0][l], s.nrm[1][l], s.nrm[2][l]) = (h.normal.x, h.normal.y, h.normal.z);
                s.given[l] = true;
            }
            (None, PrimKind::Sphere) => {
                let c = prims.spheres[prim.index()].shape.center;
                (s.geo[0][l], s.geo[1][l], s.geo[2][l]) = (c.x, c.y, c.z);
                s.sphere[l] = true;
            }
            (None, PrimKind::Triangle) => {
                let v = &prims.triangles[prim.index()].shape.v;
                for (j, c) in [v[0], v[1], v[2]].iter().flat_map(|v| v.to_array()).enumerate() {
                    s.geo[j][l] = c;
                }
            }
            (None, _) => {
                let h = prims.hit(prim, &p.ray(i), h.t, h.part);
                (s.nrm[0][l], s.nrm[1][l], s.nrm[2][l]) = (h.normal.x, h.normal.y, h.normal.z);
                s.given[l] = true;
            }
        }
        s.kind[l] = m.kind as u32;
        s.flags[l] = m.flags;
        s.emits[l] = m.emits;
        s.sampled[l] = m.light && matches!(prim.kind(), PrimKind::Triangle | PrimKind::Sphere);
        for a in 0..3 {
            s.color[a][l] = m.color[a];
            s.radiance[a][l] = m.radiance[a];
        }
        s.ior[l] = m.ior;
        s.roughness[l] = m.roughness;
        if RICH {
            s.metallic[l] = m.metallic;
        }
        if RICH && prim.kind() == PrimKind::Triangle && !g.triangle_attrs.is_empty() {
            let i = prim.index();
            s.smooth[l] = g.triangle_attrs[i].flags & ATTR_NORMALS != 0;
            s.surf[l] = s.smooth[l] || m.color_texture != 0 || m.metal_rough_texture != 0;
            if s.surf[l] {
                s.tri[l] = i as u32;
                let gt = &g.triangles[i];
                for (j, c) in gt.va.iter().chain(&gt.vb).chain(&gt.vc).enumerate() {
                    s.corners[j][l] = *c;
                }
                (s.color_tex[l], s.mr_tex[l]) = (m.color_texture, m.metal_rough_texture);
            }
        }
    }
    s
}

/// The lanes' vertices: their paths' state, the hit, the surface and the material's lane kind.
pub(super) struct Vertex<const N: usize> {
    pub on: M<N>,
    pub hit: M<N>,
    pub o: V<N>,
    pub d: V<N>,
    pub t: F<N>,
    /// The hit's normal (geometric, not yet facing the ray).
    pub n: V<N>,
    /// The interpolated normal where vertex normals are, else `n`.
    pub shading: V<N>,
    pub beta: V<N>,
    pub sum: V<N>,
    /// The density of the BSDF sample that made the ray.
    pub pdf_b: F<N>,
    pub seg: U<N>,
    /// The ray left a specular vertex (or the camera).
    pub specular: M<N>,
    pub rng: U<N>,
    pub kind: U<N>,
    pub color: V<N>,
    pub radiance: V<N>,
    pub metallic: F<N>,
    pub roughness: F<N>,
}

impl<const N: usize> Vertex<N> {
    #[inline(always)]
    pub fn is(&self, k: Kind) -> M<N> {
        self.kind.eq(U::splat(k as u32))
    }
}

/// The vertices of paths `k .. k + N` from what [`gather`] read: the paths' state, the hit's
/// normal (`Sphere::normal`: unit_or of the centre-to-hit vector, −d where that has no length;
/// `Triangle::normal`: the face normal, normalised; or as given), and `surface::surface` where
/// the lanes read textures or vertex normals: the base colour times the colour texture, the
/// pbr factors times the metallic-roughness texture's blue and green, the interpolated normal
/// (elsewhere the material and the face's normal, which is what `surface::surface` gives there
/// too).
#[inline(always)]
pub(super) fn vertex<const N: usize, const RICH: bool>(
    inp: &ShadeInputs,
    facts: &Facts,
    p: &Paths,
    k: usize,
    s: &Gathered<N>,
) -> Vertex<N> {
    let zero = F::splat(0.0);
    let (o, d) = (V::<N>::load(&p.o, k), V::<N>::load(&p.d, k));
    let t = F(s.t);
    let to_hit = (o - V::new(F(s.geo[0]), F(s.geo[1]), F(s.geo[2]))) + d.scale(t);
    let l2 = to_hit.dot(to_hit);
    let usable = l2.gt(zero) & l2.lt(F::splat(f32::INFINITY));
    let sphere_n = usable.select_v(to_hit.normalize(), -d);
    // (No closures here: the compiler may leave one out of line, in code without the ISA's
    // instructions.)
    let (e1, e2) = (V::nth(&s.geo, 1) - V::nth(&s.geo, 0), V::nth(&s.geo, 2) - V::nth(&s.geo, 0));
    let face = V::new(e1.y * e2.z - e1.z * e2.y, e1.z * e2.x - e1.x * e2.z, e1.x * e2.y - e1.y * e2.x);
    let computed = M::from_bools(&s.sphere).select_v(sphere_n, face.normalize());
    let n = M::from_bools(&s.given).select_v(V::from_rows(&s.nrm), computed);
    let mut v = Vertex {
        on: M::from_bools(&s.on),
        hit: M::from_bools(&s.is_hit),
        o,
        d,
        t,
        n,
        shading: n,
        beta: V::<N>::load(&p.beta, k),
        sum: V::<N>::load(&p.sum, k),
        pdf_b: F::<N>::load(&p.pdf, k),
        seg: U::<N>::load(&p.seg, k),
        specular: !U::<N>::load(&p.specular, k).eq(U::splat(0)),
        rng: U::<N>::load(&p.rng, k),
        kind: U(s.kind),
        color: V::from_rows(&s.color),
        radiance: V::from_rows(&s.radiance),
        metallic: F(s.metallic),
        roughness: F(s.roughness),
    };
    if RICH && s.surf.iter().any(|&x| x) {
        let g = inp.flat;
        let (p0, p1, p2) = (V::nth(&s.corners, 0), V::nth(&s.corners, 1), V::nth(&s.corners, 2));
        let (b, c) = lane_surface::barycentrics(p0, p1, p2, o + d.scale(t));
        let w = [F::splat(1.0) - b - c, b, c];
        let tc = lane_surface::texture(g, &facts.texels, s.surf, s.color_tex, s.tri, w);
        v.color = v.color.mul_elem(V::new(tc[0], tc[1], tc[2]));
        let mr = lane_surface::texture(g, &facts.texels, s.surf, s.mr_tex, s.tri, w);
        let has_mr = !U(s.mr_tex).eq(U::splat(0));
        v.roughness = has_mr.select(v.roughness * mr[1], v.roughness);
        v.metallic = has_mr.select(v.metallic * mr[2], v.metallic);
        v.shading = lane_surface::normals(g, s.surf, s.tri, w, n);
    }
    v
}
