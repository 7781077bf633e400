//! A bundle's vertices shaded lane by lane: [`path::shade_vertex`] over SIMD lanes.
//!
//! The common vertices (a diffuse, emissive, smooth or rough mirror, glass or
//! metallic-roughness surface, with colour and metallic-roughness textures read bilinearly
//! and vertex normals, or the background or environment map, in a scene without point and
//! directional lights) are shaded by loops over the lanes, which the compiler turns into
//! vector instructions; each loop calls the one-path tracer's own routines ([`spawn_origin`],
//! [`power_heuristic`], [`surface::shading_frame`], ...) or performs its operations in the
//! same order ([`pbr`], [`lane_surface`], [`lane_env`]), so every lane computes what
//! [`path::shade_vertex`] computes, bit for bit. Steps that do not vectorise (choosing a
//! light, fetching texels) run lane after lane between the loops. Every other vertex is
//! shaded by [`path::shade_vertex`] itself.

use super::environment as lane_env;
use super::guide::Guides;
use super::lights;
use super::paths::Paths;
use super::pbr::{self, basis, schlick};
use super::surface as lane_surface;
use super::texels::{self, Texels};
use crate::accel::wide::prefetch_all;
use crate::path::{self, NeeRay};
use crate::shade::ShadeInputs;
use strahl_core::layout::{
    ATTR_COLORS, ATTR_NORMALS, FlatScene, LIGHT_STAND_IN, MATERIAL_ALPHA, MATERIAL_TWO_SIDED, MATERIAL_UNLIT,
    TEXTURE_NEAREST,
};
use strahl_core::math::lanes::{F, M, U, V};
use strahl_core::math::{Ray, V3};
use strahl_core::primitives::{Hit, Nearest, PrimKind};
use strahl_core::render::bsdf::MIN_ROUGHNESS;
use strahl_core::render::limits::SHADOW_REACH;
use strahl_core::render::sampler::{PCG_INC, PCG_MULT};
use strahl_core::render::spawn::MIN_ULP;
use strahl_core::render::{environment, surface};
use strahl_core::scene::MaterialKind;

const INV_PI: f32 = std::f32::consts::FRAC_1_PI;

/// What the lanes' shading may take for granted in a scene, found once per render.
pub struct Facts {
    /// The scene has no point or directional light.
    pub lanes_ok: bool,
    /// Per material: what the lanes read of it, where they shade it (kind [`Kind`]; colour
    /// and metallic-roughness textures without nearest filtering, on diffuse and pbr
    /// materials only; no emission or normal texture, no alpha, not unlit).
    pub materials: Vec<Option<Material>>,
    /// Area lights are sampled in lanes ([`lights::in_lanes`]).
    pub lights_in_lanes: bool,
    /// The guides of the searches that pick an emitter and an environment map's cell.
    pub(super) guides: Guides,
    /// The colour, metallic-roughness and environment textures the lanes read, decoded.
    pub(super) texels: Texels,
    /// The lanes shade pbr materials, textures, vertex normals or an environment here: a
    /// scene without them is shaded by code compiled without them (the Cornell box 0.555 s
    /// against 0.58 s with them compiled in).
    pub rich: bool,
    /// The render's choice of walks, measured as it goes.
    choice: std::sync::Mutex<super::Choice>,
}

/// What the lanes read of a material, side by side.
#[derive(Clone, Copy, Debug)]
pub struct Material {
    pub kind: Kind,
    pub flags: u32,
    /// Emissive (its emission is added where a path meets it).
    pub emits: bool,
    /// [`strahl_core::layout::FlatMaterial::is_light`].
    pub light: bool,
    pub color: [f32; 3],
    pub radiance: [f32; 3],
    pub ior: f32,
    pub metallic: f32,
    pub roughness: f32,
    /// 1 + the colour texture's index (0: none).
    pub color_texture: u32,
    /// 1 + the metallic-roughness texture's index (0: none; pbr only).
    pub metal_rough_texture: u32,
}

/// The materials the lanes shade.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Diffuse, and emissive (Lambertian beneath its emission).
    Lambert = 0,
    Mirror = 1,
    Glass = 2,
    /// glTF's metallic-roughness material ([`pbr`]).
    Pbr = 3,
    /// A rough (GGX) mirror.
    Rough = 4,
}

impl Facts {
    /// The facts of `g` with `num_lights` lights; `walk`: the walk every ray after the camera's
    /// takes (None: the faster, measured).
    pub fn new(g: &FlatScene, num_lights: u32, walk: Option<super::Walk>) -> Self {
        let delta = g.lights[..num_lights as usize].iter().any(|l| l.flags & LIGHT_STAND_IN == 0);
        let materials: Vec<Option<Material>> = g
            .materials
            .iter()
            .map(|m| {
                let bilinear = |t: u32| t == 0 || g.textures[t as usize - 1].flags & TEXTURE_NEAREST == 0;
                let plain = m.radiance_texture == 0
                    && m.normal_texture == 0
                    && m.flags & (MATERIAL_ALPHA | MATERIAL_UNLIT) == 0
                    && bilinear(m.color_texture)
                    && bilinear(m.metal_rough_texture);
                let untextured = m.color_texture == 0 && m.metal_rough_texture == 0;
                let kind = match m.kind() {
                    MaterialKind::Diffuse | MaterialKind::Emissive => Some(Kind::Lambert),
                    MaterialKind::Mirror if untextured => {
                        Some(if m.roughness < MIN_ROUGHNESS { Kind::Mirror } else { Kind::Rough })
                    }
                    MaterialKind::Dielectric if untextured => Some(Kind::Glass),
                    MaterialKind::Pbr => Some(Kind::Pbr),
                    _ => None,
                };
                kind.filter(|_| plain).map(|kind| Material {
                    kind,
                    flags: m.flags,
                    emits: matches!(m.kind(), MaterialKind::Emissive | MaterialKind::Pbr),
                    light: m.is_light(),
                    color: m.color,
                    radiance: m.radiance,
                    ior: m.ior,
                    metallic: m.metallic,
                    roughness: m.roughness,
                    color_texture: m.color_texture,
                    metal_rough_texture: if kind == Kind::Pbr { m.metal_rough_texture } else { 0 },
                })
            })
            .collect();
        let rich = !g.environment.is_empty()
            || g.triangle_attrs.iter().any(|a| a.flags & ATTR_NORMALS != 0)
            || materials
                .iter()
                .flatten()
                .any(|m| m.kind == Kind::Pbr || m.color_texture != 0 || m.metal_rough_texture != 0);
        let map = lane_env::map(g).map(|e| e.texture as usize);
        let used = materials.iter().flatten().flat_map(|m| [m.color_texture, m.metal_rough_texture]);
        let used = used.filter(|&t| t != 0).map(|t| t as usize - 1).chain(map);
        Self {
            texels: Texels::new(g, used, texels::BUDGET),
            lanes_ok: !delta,
            rich,
            materials,
            lights_in_lanes: lights::in_lanes(g),
            guides: Guides::new(g, lane_env::map(g)),
            choice: std::sync::Mutex::new(super::Choice::forced(walk)),
        }
    }

    /// The render's choice of walks so far.
    pub(super) fn walks(&self) -> super::Choice {
        *self.choice.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Adds a measurement of `walk` for rays of `kind` to the render's choice.
    pub(super) fn record_walk(&self, kind: usize, walk: super::Walk, spent: std::time::Duration, rays: usize) {
        self.choice.lock().unwrap_or_else(|e| e.into_inner()).record(kind, walk, spent, rays);
    }
}

/// Asks for what [`shade`] reads of the primitives `hits` met (their tags and shapes, and a
/// triangle's corners and attributes), ahead of it: in a large mesh each is a cache miss,
/// and the shading's loop over the lanes would wait for them one after the other.
#[inline(always)]
pub(super) fn prefetch(inp: &ShadeInputs, hits: &[Nearest<f32>]) {
    let (g, prims) = (inp.flat, inp.prims);
    for h in hits.iter().filter(|h| h.found) {
        let i = h.prim_ref.index();
        match h.prim_ref.kind() {
            PrimKind::Triangle => {
                prefetch_all(&prims.triangles[i]);
                if let (Some(t), Some(a)) = (g.triangles.get(i), g.triangle_attrs.get(i)) {
                    prefetch_all(t);
                    prefetch_all(a);
                }
            }
            PrimKind::Sphere => prefetch_all(&prims.spheres[i]),
            _ => {}
        }
    }
}

/// Shades the vertices of paths `k .. k + n` (n ≤ N) where their rays met `hits[..n]` (with
/// their records where the walk made them, else made here), as
/// [`path::shade_vertex`] does (`RICH`: [`Facts::rich`], else that code is left out): updates the paths, sets `more[k + l]` for each that goes on,
/// and pushes each area-light shadow ray with its path's index onto `nee`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn shade<const N: usize, const RICH: bool>(
    inp: &ShadeInputs,
    facts: &Facts,
    p: &mut Paths,
    k: usize,
    n_lanes: usize,
    hits: &[Nearest<f32>],
    records: Option<&[Option<Hit<f32>>]>,
    more: &mut [bool],
    nee: &mut Vec<(u32, NeeRay)>,
) {
    let (f, g, prims) = (inp.frame, inp.flat, inp.prims);
    debug_assert!(n_lanes <= N && k + N <= p.capacity());

    // Lane after lane: which lanes the loops shade, and what they read of the hit and its
    // material; the others are shaded by the one-path code now.
    let mut on = [false; N];
    let mut is_hit = [false; N];
    let mut t = [0.0f32; N];
    let mut nrm = [[0.0f32; N]; 3];
    let mut kind = [0u32; N];
    let mut flags = [0u32; N];
    let mut emits = [false; N];
    let mut sampled = [false; N];
    let mut color = [[0.0f32; N]; 3];
    let mut radiance = [[0.0f32; N]; 3];
    let mut ior = [1.0f32; N];
    // Geometry for the normals the lanes compute: a sphere's centre, a triangle's vertices
    // (a cylinder's or a plane's normal comes from Primitives::hit here).
    let mut geo = [[0.0f32; N]; 9];
    let mut sphere = [false; N];
    let mut given = [false; N];
    // Triangles with attributes whose textures or vertex normals the lanes read: the
    // triangle, its corners (for the barycentric weights), the textures, the pbr factors.
    let mut surf = [false; N];
    let mut smooth = [false; N];
    let mut tri = [0u32; N];
    let mut corners = [[0.0f32; N]; 9];
    let (mut color_tex, mut mr_tex) = ([0u32; N], [0u32; N]);
    let (mut metallic, mut roughness) = ([0.0f32; N], [0.0f32; N]);
    for l in 0..n_lanes {
        let i = k + l;
        let b = &hits[l];
        let prim = b.prim_ref;
        let mi = if b.found { prims.tag(prim).material as usize } else { 0 };
        let lane_kind = if !facts.lanes_ok {
            None
        } else if !b.found {
            Some(None)
        } else {
            let plain = prim.kind() != PrimKind::Triangle
                || g.triangle_attrs.is_empty()
                || g.triangle_attrs[prim.index()].flags & ATTR_COLORS == 0;
            facts.materials[mi].filter(|_| plain).map(Some)
        };
        match lane_kind {
            None => {
                let (mut st, mut rng) = p.get(i);
                let hit = match records {
                    Some(r) => r[l],
                    None => b.found.then(|| prims.hit(prim, &st.ray, b.t, b.part)),
                };
                let mut ne = None;
                more[i] = path::shade_vertex(inp, &mut st, hit.as_ref(), &mut rng, &mut ne);
                p.set(i, &st, &rng);
                if let Some(x) = ne {
                    nee.push((i as u32, x));
                }
            }
            Some(None) => on[l] = true,
            Some(Some(m)) => {
                on[l] = true;
                is_hit[l] = true;
                t[l] = b.t;
                match (records.and_then(|r| r[l]), prim.kind()) {
                    // The walk's own record (its triangle copy gave the normal).
                    (Some(h), _) => {
                        (nrm[0][l], nrm[1][l], nrm[2][l]) = (h.normal.x, h.normal.y, h.normal.z);
                        given[l] = true;
                    }
                    (None, PrimKind::Sphere) => {
                        let c = prims.spheres[prim.index()].shape.center;
                        (geo[0][l], geo[1][l], geo[2][l]) = (c.x, c.y, c.z);
                        sphere[l] = true;
                    }
                    (None, PrimKind::Triangle) => {
                        let v = &prims.triangles[prim.index()].shape.v;
                        for (j, c) in [v[0], v[1], v[2]].iter().flat_map(|v| v.to_array()).enumerate() {
                            geo[j][l] = c;
                        }
                    }
                    (None, _) => {
                        let h = prims.hit(prim, &p.ray(i), b.t, b.part);
                        (nrm[0][l], nrm[1][l], nrm[2][l]) = (h.normal.x, h.normal.y, h.normal.z);
                        given[l] = true;
                    }
                }
                kind[l] = m.kind as u32;
                flags[l] = m.flags;
                emits[l] = m.emits;
                sampled[l] = m.light && matches!(prim.kind(), PrimKind::Triangle | PrimKind::Sphere);
                for a in 0..3 {
                    color[a][l] = m.color[a];
                    radiance[a][l] = m.radiance[a];
                }
                ior[l] = m.ior;
                roughness[l] = m.roughness;
                if RICH {
                    metallic[l] = m.metallic;
                }
                if RICH && prim.kind() == PrimKind::Triangle && !g.triangle_attrs.is_empty() {
                    let i = prim.index();
                    smooth[l] = g.triangle_attrs[i].flags & ATTR_NORMALS != 0;
                    surf[l] = smooth[l] || m.color_texture != 0 || m.metal_rough_texture != 0;
                    if surf[l] {
                        tri[l] = i as u32;
                        let gt = &g.triangles[i];
                        for (j, c) in gt.va.iter().chain(&gt.vb).chain(&gt.vc).enumerate() {
                            corners[j][l] = *c;
                        }
                        (color_tex[l], mr_tex[l]) = (m.color_texture, m.metal_rough_texture);
                    }
                }
            }
        }
    }
    let bg = V::splat(f.background);
    let one = F::splat(1.0);
    let zero = F::splat(0.0);
    let v3 = |a: &[[f32; N]; 3], l: usize| V3::new(a[0][l], a[1][l], a[2][l]);
    let on_m = M::from_bools(&on);
    let hit_m = M::from_bools(&is_hit);
    let lambert = U(kind).eq(U::splat(Kind::Lambert as u32));
    let glass = U(kind).eq(U::splat(Kind::Glass as u32));
    let is_pbr = if RICH { U(kind).eq(U::splat(Kind::Pbr as u32)) } else { M([0; N]) };
    let any_pbr = RICH && (0..n_lanes).any(|l| on[l] && kind[l] == Kind::Pbr as u32);
    let is_rough = U(kind).eq(U::splat(Kind::Rough as u32));
    let any_rough = (0..n_lanes).any(|l| on[l] && kind[l] == Kind::Rough as u32);

    // The lanes' paths.
    let (o, d) = (V::<N>::load(&p.o, k), V::<N>::load(&p.d, k));
    let beta = V::<N>::load(&p.beta, k);
    let mut sum = V::<N>::load(&p.sum, k);
    let (pdf_b, seg) = (F::<N>::load(&p.pdf, k), U::<N>::load(&p.seg, k));
    let specular = U::<N>::load(&p.specular, k).eq(U::splat(0));
    let specular = !specular;
    let mut rng = U::<N>::load(&p.rng, k);
    let t = F(t);
    // The hit's normal: Sphere::normal (unit_or of the centre-to-hit vector, −d where that
    // has no length), Triangle::normal (the face normal, normalised), or as given.
    let to_hit = (o - V::new(F(geo[0]), F(geo[1]), F(geo[2]))) + d.scale(t);
    let l2 = to_hit.dot(to_hit);
    let usable = l2.gt(zero) & l2.lt(F::splat(f32::INFINITY));
    let sphere_n = usable.select_v(to_hit.normalize(), -d);
    // (No closures here: the compiler may leave one out of line, in code without the ISA's
    // instructions.)
    let (e1, e2) = (V::nth(&geo, 1) - V::nth(&geo, 0), V::nth(&geo, 2) - V::nth(&geo, 0));
    let face = V::new(e1.y * e2.z - e1.z * e2.y, e1.z * e2.x - e1.x * e2.z, e1.x * e2.y - e1.y * e2.x);
    let computed = M::from_bools(&sphere).select_v(sphere_n, face.normalize());
    let n = M::from_bools(&given).select_v(V::from_rows(&nrm), computed);
    let mut color = V::from_rows(&color);
    let radiance = V::from_rows(&radiance);
    let (mut metallic, mut roughness) = (F(metallic), F(roughness));
    // surface::surface where the lanes read textures or vertex normals: the base colour times
    // the colour texture, the pbr factors times the metallic-roughness texture's blue and
    // green, the interpolated normal (elsewhere the material and the face's normal, which is
    // what surface::surface gives there too).
    let mut shading = n;
    if RICH && surf.iter().any(|&s| s) {
        let (p0, p1, p2) = (V::nth(&corners, 0), V::nth(&corners, 1), V::nth(&corners, 2));
        let (b, c) = lane_surface::barycentrics(p0, p1, p2, o + d.scale(t));
        let w = [one - b - c, b, c];
        let tc = lane_surface::texture(g, &facts.texels, surf, color_tex, tri, w);
        color = color.mul_elem(V::new(tc[0], tc[1], tc[2]));
        let mr = lane_surface::texture(g, &facts.texels, surf, mr_tex, tri, w);
        let has_mr = !U(mr_tex).eq(U::splat(0));
        roughness = has_mr.select(roughness * mr[1], roughness);
        metallic = has_mr.select(metallic * mr[2], metallic);
        shading = lane_surface::normals(g, surf, tri, w, n);
    }

    // The background of a miss (weighted against next-event estimation's samples of the
    // environment, lane after lane, where there is one); the emission of an emissive hit,
    // weighted against the light samples.
    let alive = seg.le(U::splat(f.max_depth));
    // (Loops rather than array::from_fn, whose closures the compiler leaves uninlined in a
    // function this size.)
    let mut miss = [false; N];
    for l in 0..N {
        miss[l] = on[l] && !is_hit[l] && alive.lane(l);
    }
    let (bg, w) = if !RICH || g.environment.is_empty() {
        (bg, one)
    } else if let Some(e) = lane_env::map(g) {
        if miss.contains(&true) {
            let (c, p_env) = lane_env::radiance_and_pdf(g, &facts.texels, &facts.guides, e, d, miss);
            let p_env = specular.select(zero, p_env);
            (c, p_env.gt(zero).select(power_heuristic(pdf_b, p_env), one))
        } else {
            (bg, one)
        }
    } else {
        let (mut c, mut w) = ([[0.0f32; N]; 3], [1.0f32; N]);
        let dr = d.rows();
        for l in 0..n_lanes {
            if !miss[l] {
                continue;
            }
            let dir = v3(&dr, l);
            let pdf_env = if specular.lane(l) { 0.0 } else { environment::pdf(g, dir) };
            if pdf_env > 0.0 {
                w[l] = strahl_core::render::emitters::power_heuristic(pdf_b.0[l], pdf_env);
            }
            let b = environment::background(g, f, dir);
            (c[0][l], c[1][l], c[2][l]) = (b.x, b.y, b.z);
        }
        (V::from_rows(&c), F(w))
    };
    let s_miss = sum + beta.mul_elem(bg).scale(w);
    let cos_l = emitted_cos(U(flags), -d.dot(n));
    let mean = (radiance.x + radiance.y + radiance.z) / F::splat(3.0);
    let light_pdf = mean * F::splat(f.emitter_norm) * (t * t) / cos_l;
    let w_e = (specular | !M::from_bools(&sampled)).select(one, power_heuristic(pdf_b, light_pdf));
    let s_emit = sum + beta.mul_elem(radiance).scale(w_e);
    let emit = M::from_bools(&emits) & cos_l.gt(zero);
    let s_hit = emit.select_v(s_emit, sum);
    sum = (alive & hit_m).select_v(s_hit, (alive & !hit_m).select_v(s_miss, sum));
    if !is_hit.contains(&true) {
        // No lane shaded here met a surface (misses only; the one-path code has shaded the
        // others): none scatters, so each ends with its sum, its random stream untouched;
        // what follows would change nothing.
        for (a, s) in [sum.x, sum.y, sum.z].into_iter().enumerate() {
            put(&mut p.sum[a], k, s, on_m);
        }
        for l in 0..n_lanes {
            if on[l] {
                more[k + l] = false;
            }
        }
        return;
    }
    // The six numbers of the light and BSDF samples.
    let cont = alive & hit_m & !seg.eq(U::splat(f.max_depth));
    let mut u = [F::splat(0.0); 6];
    for x in &mut u {
        *x = draw(&mut rng, cont);
    }
    let front = d.dot(n).lt(zero);
    let ng = front.select_v(n, -n);
    let x = o + d.scale(t);

    // The light sample of each Lambertian, pbr and rough mirror vertex.
    let nee_kind = lambert | is_pbr | is_rough;
    let mut want = [false; N];
    for l in 0..N {
        want[l] = on[l] && cont.lane(l) && nee_kind.lane(l);
    }
    let ls = lights::sample(g, f, facts.lights_in_lanes, &facts.guides, &facts.texels, x, [u[0], u[1], u[2]], want);
    let wo = -d;
    let smooth = M::from_bools(&smooth) & on_m & cont;
    let ns = shading_normal(U(kind), front, n, shading, wo, smooth);
    // The pbr lobes seen from wo.
    let lobes = if any_pbr { Some(pbr::lobes(color, metallic, roughness, wo.dot(ns))) } else { None };

    // The light sample's value (bsdf::eval's Lambertian branch, behind path::eval_above's
    // face test) and its shadow ray.
    let wi = ls.dir;
    let cos_i = wi.dot(ns);
    let above = wi.dot(ng).gt(zero) & cos_i.gt(zero);
    let mut fc = above.select_v(color.scale(cos_i * F::splat(INV_PI)), V::splat([0.0; 3]));
    let mut pdf_l = above.select(cos_i * F::splat(INV_PI), zero);
    if let Some(lobes) = &lobes {
        // path::eval_above's face test, bsdf::eval's, then the material's own.
        let (pf, pp) = pbr::eval(lobes, wo, wi, ns);
        let face = !wi.dot(ng).le(zero) & !cos_i.le(zero);
        fc = (is_pbr & face).select_v(pf, (is_pbr & !face).select_v(V::splat([0.0; 3]), fc));
        pdf_l = (is_pbr & face).select(pp, (is_pbr & !face).select(zero, pdf_l));
    }
    if any_rough {
        let (rf, rp) = pbr::conductor_eval(roughness, color, wo, wi, ns);
        let face = !wi.dot(ng).le(zero);
        fc = (is_rough & face).select_v(rf, (is_rough & !face).select_v(V::splat([0.0; 3]), fc));
        pdf_l = (is_rough & face).select(rp, (is_rough & !face).select(zero, pdf_l));
    }
    let value = beta.mul_elem(fc).mul_elem(ls.value).scale(power_heuristic(ls.pdf, pdf_l));
    let nee_m = cont & nee_kind & ls.on & fc.max_component().gt(zero);
    let nee_o = spawn_origin(o, d, t, ng);

    // The BSDF sample. Glass: reflect or refract by the Fresnel term.
    let cos_g = wo.dot(ns);
    let eta = front.select(F(ior), one / F(ior));
    let fres = fresnel_dielectric(cos_g, eta);
    let reflects = u[3].lt(fres);
    let inv_eta = one / eta;
    let glass_dir = reflects.select_v(reflect(-wo, ns), refract(-wo, ns, cos_g, inv_eta));
    let glass_w = reflects.select_v(V::splat([1.0; 3]), color / (eta * eta));
    // A smooth mirror.
    let mirror_dir = reflect(-wo, ns);
    let mirror_w = schlick(color, cos_g);
    // Lambertian: a cosine-weighted direction about the shading normal; its angle's sine and
    // cosine lane after lane.
    let mut has_bs = cont & (!lambert | color.max_component().gt(zero));
    let (sin_phi, cos_phi) = u[5].sin_cos_turns();
    let r = u[4].sqrt();
    let local = V::new(r * cos_phi, r * sin_phi, (one - u[4]).max(zero).sqrt());
    let (tb, bb) = basis(ns);
    let world = (tb.scale(local.x) + bb.scale(local.y) + ns.scale(local.z)).normalize();
    let mut dir = lambert.select_v(world, glass.select_v(glass_dir, mirror_dir));
    let mut weight = lambert.select_v(color, glass.select_v(glass_w, mirror_w));
    let mut pdf = lambert.select(local.z * F::splat(INV_PI), zero);
    if let Some(lobes) = &lobes {
        // bsdf::pbr_sample: the lobe by u[3], its direction by u[4], u[5] (the diffuse base's
        // is the Lambertian one above), weighed by bsdf::pbr_eval.
        let pd = pbr::sample_dir(lobes, wo, ns, [u[3], u[4], u[5]], world);
        let (pf, pp) = pbr::eval(lobes, wo, pd, ns);
        let ok = pbr::samples(lobes, wo.dot(ns)) & pp.gt(zero);
        has_bs = (is_pbr & cont & ok) | (!is_pbr & has_bs);
        dir = is_pbr.select_v(pd, dir);
        weight = is_pbr.select_v(pf / pp, weight);
        pdf = is_pbr.select(pp, pdf);
    }

    if any_rough {
        // bsdf::sample's rough mirror, by u[4], u[5].
        let (ok, rd, rw, rp) = pbr::conductor_sample(roughness, color, wo, ns, u[4], u[5]);
        has_bs = (is_rough & cont & ok) | (!is_rough & has_bs);
        dir = is_rough.select_v(rd, dir);
        weight = is_rough.select_v(rw, weight);
        pdf = is_rough.select(rp, pdf);
    }

    // The face test, the path weight, Russian roulette and the next ray.
    let leaks = !glass & dir.dot(ng).le(zero);
    let b = beta.mul_elem(weight);
    let roulette = U::splat(f.rr_depth).le(seg);
    let q = b.max_component().min(F::splat(0.95));
    let plays = has_bs & !leaks & roulette;
    let survives = draw(&mut rng, plays).lt(q) | !plays;
    let b = roulette.select_v(b / q, b);
    let go = on_m & has_bs & !leaks & survives;
    let side = dir.dot(n).ge(zero).select_v(n, -n);
    let origin = spawn_origin(o, d, t, side);

    // Written back, for the lanes shaded here (the one-path code wrote the others').
    #[inline(always)]
    fn put<const N: usize>(v: &mut [f32], k: usize, new: F<N>, m: M<N>) {
        let old = F::<N>::load(v, k);
        v[k..k + N].copy_from_slice(&m.select(new, old).0);
    }
    #[inline(always)]
    fn put_u<const N: usize>(v: &mut [u32], k: usize, new: U<N>, m: M<N>) {
        let old = U::<N>::load(v, k);
        v[k..k + N].copy_from_slice(&m.select_u(new, old).0);
    }
    for (a, (nd, nb)) in [(origin.x, dir.x), (origin.y, dir.y), (origin.z, dir.z)].into_iter().enumerate() {
        put(&mut p.o[a], k, nd, go);
        put(&mut p.d[a], k, nb, go);
    }
    for (a, (nb, ns_)) in [(b.x, sum.x), (b.y, sum.y), (b.z, sum.z)].into_iter().enumerate() {
        put(&mut p.beta[a], k, nb, go);
        put(&mut p.sum[a], k, ns_, on_m);
    }
    put(&mut p.pdf, k, pdf, go);
    put_u(&mut p.specular, k, (!nee_kind).select_u(U::splat(1), U::splat(0)), go);
    put_u(&mut p.seg, k, seg.wrapping_add(U::splat(1)), go);
    put_u(&mut p.rng, k, rng, on_m);

    // Lane after lane: what goes on, and the shadow rays.
    let (no, wv, lsd) = (nee_o.rows(), value.rows(), ls.dir.rows());
    for l in 0..n_lanes {
        if !on[l] {
            continue;
        }
        more[k + l] = go.lane(l);
        if nee_m.lane(l) {
            let ray = Ray::new(v3(&no, l), v3(&lsd, l));
            nee.push(((k + l) as u32, NeeRay { ray, dist: ls.dist.0[l] * SHADOW_REACH, value: v3(&wv, l) }));
        }
    }
}

/// The shading normal of [`surface::shading_frame`] for materials of lane kinds `kind`, seen
/// from `wo` on the `front` side of face normal `n`, with interpolated normal `shading` where
/// `smooth`, else the face's (which is what shading_frame gives there for every material: its
/// mirrors' and pbr surfaces' reflecting_normal keeps a normal that is the face's). Where a
/// mirror's or pbr lane's normal fails [`surface::reflecting_normal`]'s first test, that
/// routine bends it, lane after lane.
// (A lane loop over several arrays indexed by the lane.)
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn shading_normal<const N: usize>(kind: U<N>, front: M<N>, n: V<N>, shading: V<N>, wo: V<N>, smooth: M<N>) -> V<N> {
    let is = |k: Kind| kind.eq(U::splat(k as u32));
    let ng = front.select_v(n, -n);
    let turned = front.select_v(shading, -shading);
    let to_face = is(Kind::Glass) | turned.dot(wo).le(F::splat(0.0));
    let wz = wo.dot(ng);
    let keeps = (F::splat(2.0) * wo.dot(turned) * turned.dot(ng) - wz).ge((F::splat(0.9) * wz).min(F::splat(0.01)));
    let reflects = is(Kind::Mirror) | is(Kind::Rough) | is(Kind::Pbr);
    let ns = (smooth & !to_face).select_v(turned, ng);
    let bend = smooth & !to_face & reflects & !keeps;
    if !(0..N).any(|l| bend.lane(l)) {
        return ns;
    }
    let v3 = |a: &[[f32; N]; 3], l: usize| V3::new(a[0][l], a[1][l], a[2][l]);
    let (mut rows, t, g, w) = (ns.rows(), turned.rows(), ng.rows(), wo.rows());
    for l in 0..N {
        if bend.lane(l) {
            let b = surface::reflecting_normal(v3(&g, l), v3(&w, l), v3(&t, l));
            (rows[0][l], rows[1][l], rows[2][l]) = (b.x, b.y, b.z);
        }
    }
    V::from_rows(&rows)
}

/// [`Sampler::next_f32`] in every lane, the stream advanced where `on`.
#[inline(always)]
fn draw<const N: usize>(rng: &mut U<N>, on: M<N>) -> F<N> {
    let old = *rng;
    *rng = on.select_u(old.wrapping_mul(U::splat(PCG_MULT)).wrapping_add(U::splat(PCG_INC)), old);
    // sampler's permute: RXS-M-XS.
    let shift = (old >> U::splat(28)).wrapping_add(U::splat(4));
    let word = ((old >> shift) ^ old).wrapping_mul(U::splat(277_803_737));
    let out = (word >> U::splat(22)) ^ word;
    out.top24_f32() * F::splat(1.0 / 16_777_216.0)
}

/// [`path::power_heuristic`].
#[inline(always)]
fn power_heuristic<const N: usize>(a: F<N>, b: F<N>) -> F<N> {
    let (a2, b2) = (a * a, b * b);
    (a2 + b2).gt(F::splat(0.0)).select(a2 / (a2 + b2), F::splat(0.0))
}

/// [`emitters::emitted_cos`] for material flags `flags`.
#[inline(always)]
fn emitted_cos<const N: usize>(flags: U<N>, cos: F<N>) -> F<N> {
    let one_sided = (flags & U::splat(MATERIAL_TWO_SIDED)).eq(U::splat(0));
    one_sided.select(cos, cos.abs())
}

/// [`spawn_origin`] for the ray (o, d) hit at `t`, leaving on the side of `n`.
#[inline(always)]
fn spawn_origin<const N: usize>(o: V<N>, d: V<N>, t: F<N>, n: V<N>) -> V<N> {
    #[inline(always)]
    fn step<const N: usize>(p: F<N>, o: F<N>, t: F<N>, n: F<N>) -> F<N> {
        let min_ulp = F::splat(MIN_ULP);
        let m = (o.abs() + t.abs()).max(p.abs()).max(min_ulp);
        let ulp = F::from_bits(m.to_bits().wrapping_add(U::splat(1))) - m;
        p + F::splat(32.0) * n * ulp.max(min_ulp)
    }
    let p = o + d.scale(t);
    V::new(step(p.x, o.x, t, n.x), step(p.y, o.y, t, n.y), step(p.z, o.z, t, n.z))
}

/// [`reflect`].
#[inline(always)]
fn reflect<const N: usize>(d: V<N>, n: V<N>) -> V<N> {
    d - n.scale(F::splat(2.0) * d.dot(n))
}

/// [`refract`].
#[inline(always)]
fn refract<const N: usize>(d: V<N>, n: V<N>, cos_i: F<N>, eta: F<N>) -> V<N> {
    let one = F::splat(1.0);
    let sin2_t = eta * eta * (one - cos_i * cos_i);
    let cos_t = (one - sin2_t).max(F::splat(0.0)).sqrt();
    (d.scale(eta) + n.scale(eta * cos_i - cos_t)).normalize()
}

/// [`fresnel_dielectric`].
#[inline(always)]
fn fresnel_dielectric<const N: usize>(cos_i: F<N>, eta: F<N>) -> F<N> {
    let one = F::splat(1.0);
    let sin2_t = (one - cos_i * cos_i) / (eta * eta);
    let cos_t = (one - sin2_t).max(F::splat(0.0)).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    sin2_t.ge(one).select(one, F::splat(0.5) * (r_parl * r_parl + r_perp * r_perp))
}

#[cfg(test)]
mod tests {
    use super::super::unit_direction;
    use super::*;
    use strahl_core::layout::FlatMaterial;
    use strahl_core::render::sampler::Sampler;

    const N: usize = 16;

    /// The lanes' shading normal is surface::shading_frame's bit for bit, for every lane kind,
    /// both sides, flat and interpolated normals, and interpolated normals tilted far enough
    /// that mirrors' and pbr surfaces' reflections bend them (counted: the test needs some).
    #[test]
    fn lanes_shading_normal_equals_shading_frame() {
        let mut rng = Sampler::new(4, 5, 6);
        let kinds = [Kind::Lambert, Kind::Mirror, Kind::Glass, Kind::Pbr, Kind::Rough];
        let material = |k: Kind| {
            let kind = match k {
                Kind::Lambert => MaterialKind::Diffuse,
                Kind::Mirror | Kind::Rough => MaterialKind::Mirror,
                Kind::Glass => MaterialKind::Dielectric,
                Kind::Pbr => MaterialKind::Pbr,
            };
            FlatMaterial { kind: kind as u32, ..Default::default() }
        };
        let (mut bent, mut checked) = (0, 0);
        for _ in 0..2000 {
            let mut lanes = [[[0.0f32; N]; 3]; 3];
            let (mut kind, mut front, mut smooth) = ([0u32; N], [false; N], [false; N]);
            let mut cases = Vec::new();
            for l in 0..N {
                let k = kinds[(rng.next_f32() * 5.0) as usize % 5];
                let n = unit_direction(&mut rng);
                // Interpolated normals within about 80 degrees of the face's.
                let shading = (n + unit_direction(&mut rng) * (1.5 * rng.next_f32())).normalize();
                let wo = unit_direction(&mut rng);
                let f = rng.next_f32() < 0.5;
                let s = rng.next_f32() < 0.8;
                (kind[l], front[l], smooth[l]) = (k as u32, f, s);
                for (j, v) in [n, shading, wo].into_iter().enumerate() {
                    (lanes[j][0][l], lanes[j][1][l], lanes[j][2][l]) = (v.x, v.y, v.z);
                }
                cases.push((k, f, s, n, shading, wo));
            }
            let [n, shading, wo] = lanes.map(|r| V::from_rows(&r));
            let got = shading_normal(U(kind), M::from_bools(&front), n, shading, wo, M::from_bools(&smooth)).rows();
            for (l, &(k, f, s, n, shading, wo)) in cases.iter().enumerate() {
                let (ng, frame) = surface::shading_frame(&material(k), f, n, shading, wo);
                let want = if s { frame } else { ng };
                let turned = if f { shading } else { -shading };
                bent += (s && want != turned && want != ng) as usize;
                checked += 1;
                assert_eq!(
                    [got[0][l], got[1][l], got[2][l]].map(f32::to_bits),
                    want.to_array().map(f32::to_bits),
                    "{k:?}"
                );
            }
        }
        assert!(bent > 100, "{bent} of {checked} normals bent");
    }
}
