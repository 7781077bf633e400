//! Whitted shading (`shade.wgsl` is the twin): point and directional lights with hard
//! shadows, mirror reflection, dielectric refraction weighted by the exact Fresnel terms,
//! up to `max_depth` bounces.
//!
//! WGSL has no recursion, so the ray tree is walked with an explicit stack of
//! [`WHITTED_STACK`] entries; this code walks it in the same order so both backends add the
//! same contributions in the same order.

use crate::accel::{WideBvh, wide_traverse};
use strahl_core::layout::{FlatLight, FlatMaterial, FlatScene, FrameParams, LIGHT_POINT, MATERIAL_ALPHA};
use strahl_core::math::{Ray, V3};
use strahl_core::primitives::{Hit, Primitives};
use strahl_core::render::bsdf::{fresnel_dielectric, reflect, refract};
use strahl_core::render::camera::primary_ray;
use strahl_core::render::emitters::spot_factor;
use strahl_core::render::environment;
use strahl_core::render::limits::{SHADOW_PASSES, WHITTED_STACK};
use strahl_core::render::spawn::spawn_origin;
use strahl_core::render::{pbr, surface};
use strahl_core::scene::MaterialKind;

const INV_PI: f32 = std::f32::consts::FRAC_1_PI;

/// What the shading stage reads: geometry, the CPU's traversal layout of its BVH, and the
/// GPU-layout scene data.
pub struct ShadeInputs<'a> {
    pub prims: &'a Primitives<f32>,
    pub wide: &'a WideBvh,
    pub flat: &'a FlatScene,
    pub frame: &'a FrameParams,
}

#[derive(Clone, Copy)]
struct Pending {
    ray: Ray<f32>,
    weight: V3<f32>,
    depth: u32,
}

/// Transmittance from the hit at `t` along `from` towards a light `dist` away: 0 if an opaque
/// surface blocks it, the product of dielectric colours and of what alpha surfaces let through
/// (1 − coverage) crossed otherwise (emissive surfaces let it through).
fn shadow_transmittance(inp: &ShadeInputs, from: &Ray<f32>, t: f32, n: V3<f32>, l: V3<f32>, dist: f32) -> V3<f32> {
    let mut origin = spawn_origin(from, t, n);
    let mut remaining = dist;
    let mut tr = V3::splat(1.0f32);
    for _ in 0..SHADOW_PASSES {
        let ray = Ray::new(origin, l);
        let Some(hit) = wide_traverse::nearest(inp.wide, inp.prims, &ray, 0.0, remaining) else {
            return tr;
        };
        let m = &inp.flat.materials[hit.tag.material as usize];
        // Emissive surfaces are lights (their stand-ins sit inside them): they cast no shadow.
        if m.flags & MATERIAL_ALPHA != 0 {
            let s = surface::surface(inp.flat, m, hit.prim_ref, ray.at(hit.t), hit.normal);
            tr = tr * (1.0 - surface::coverage(m, s.alpha));
            if tr.max_component() <= 0.0 {
                return V3::zero();
            }
        } else if m.kind() == MaterialKind::Dielectric {
            tr = tr.mul_elem(V3::from_array(m.color));
        } else if m.kind() != MaterialKind::Emissive {
            return V3::zero();
        }
        // Continue from the far side of the surface just crossed.
        let side = if l.dot(hit.normal) < 0.0 { -hit.normal } else { hit.normal };
        origin = spawn_origin(&ray, hit.t, side);
        remaining -= hit.t;
    }
    V3::zero()
}

/// Direct light on a diffuse surface hit at `t` along `ray`, face normal `ng` and shading
/// normal `ns` (both on the ray's side): ambient plus Σ E·cosθ/π over unshadowed lights above
/// the face.
fn direct_light(inp: &ShadeInputs, ray: &Ray<f32>, t: f32, ng: V3<f32>, ns: V3<f32>, albedo: V3<f32>) -> V3<f32> {
    let p = ray.at(t);
    // The environment's unshadowed diffuse light joins the ambient term.
    let mut sum = V3::from_array(inp.frame.ambient) + environment::diffuse(inp.flat, ns);
    for light in &inp.flat.lights[..inp.frame.num_lights as usize] {
        let (l, dist, e) = light_at(light, p);
        let cos = ns.dot(l);
        if cos <= 0.0 || ng.dot(l) <= 0.0 {
            continue;
        }
        let tr = shadow_transmittance(inp, ray, t, ng, l, dist);
        sum += e.mul_elem(tr) * (cos * INV_PI);
    }
    albedo.mul_elem(sum)
}

/// Unit vector to the light, its distance, and the irradiance it gives a surface facing it.
#[inline]
fn light_at(light: &FlatLight, p: V3<f32>) -> (V3<f32>, f32, V3<f32>) {
    let v = V3::from_array(light.vector);
    let i = V3::from_array(light.intensity);
    if light.kind == LIGHT_POINT {
        let to = v - p;
        let d2 = to.dot(to);
        let dist = d2.sqrt();
        let dir = to / dist;
        (dir, dist, i / d2 * spot_factor(light, dir, dist))
    } else {
        (-v, f32::INFINITY, i)
    }
}

/// Radiance along a primary ray.
pub fn radiance(inp: &ShadeInputs, ray: Ray<f32>) -> V3<f32> {
    radiance_from(inp, ray, None)
}

/// [`radiance`] along a primary ray whose nearest hit is `first` where given (found by a
/// walk of several rays at once, [`super::lanes::whitted`]): the ray tree goes on from it as
/// from the hit [`radiance`]'s own walk would find.
pub fn radiance_from(inp: &ShadeInputs, ray: Ray<f32>, first: Option<Option<Hit<f32>>>) -> V3<f32> {
    let mut first = first;
    let mut stack = [Pending { ray, weight: V3::zero(), depth: 0 }; WHITTED_STACK];
    stack[0].weight = V3::splat(1.0);
    let mut sp = 1usize;
    let mut color = V3::zero();
    let max_depth = inp.frame.max_depth;
    while sp > 0 {
        sp -= 1;
        let Pending { ray, weight, depth } = stack[sp];
        let found = match first.take() {
            Some(hit) => hit,
            None => wide_traverse::nearest(inp.wide, inp.prims, &ray, 0.0, f32::INFINITY),
        };
        let Some(hit) = found else {
            color += weight.mul_elem(environment::background(inp.flat, inp.frame, ray.dir));
            continue;
        };
        let untextured = &inp.flat.materials[hit.tag.material as usize];
        let s = surface::surface(inp.flat, untextured, hit.prim_ref, ray.at(hit.t), hit.normal);
        let m: &FlatMaterial = &s.m;
        let mut weight = weight;
        if m.flags & MATERIAL_ALPHA != 0 {
            // What the surface lets through goes on as a ray of its own (no bounce); the
            // surface is shaded with the rest.
            let c = surface::coverage(m, s.alpha);
            if c < 1.0 && sp < WHITTED_STACK {
                let side = if ray.dir.dot(hit.normal) >= 0.0 { hit.normal } else { -hit.normal };
                stack[sp] = Pending {
                    ray: Ray::new(spawn_origin(&ray, hit.t, side), ray.dir),
                    weight: weight * (1.0 - c),
                    depth,
                };
                sp += 1;
            }
            if c <= 0.0 {
                continue;
            }
            weight = weight * c;
        }
        let front = ray.dir.dot(hit.normal) < 0.0;
        let (ng, ns) = surface::shading_frame(m, front, hit.normal, s.normal, -ray.dir);
        let albedo = V3::from_array(m.color);
        // A mirror direction about the shading normal that falls below the face is taken
        // about the face's normal instead.
        let mirrored = || {
            let r = reflect(ray.dir, ns);
            if r.dot(ng) > 0.0 { r } else { reflect(ray.dir, ng) }
        };
        match m.kind() {
            MaterialKind::Emissive => {
                color += weight.mul_elem(V3::from_array(m.radiance));
            }
            MaterialKind::Mirror => {
                if depth < max_depth && sp < WHITTED_STACK {
                    stack[sp] = Pending {
                        ray: Ray::new(spawn_origin(&ray, hit.t, ng), mirrored()),
                        weight: weight.mul_elem(albedo),
                        depth: depth + 1,
                    };
                    sp += 1;
                }
            }
            MaterialKind::Pbr => {
                // Whitted follows one mirror ray: the lobe's sharp part (1 − r)² goes there,
                // the rest, which only a path tracer resolves, joins the diffuse light.
                let l = pbr::pbr_lobes(m, (-ray.dir).dot(ns));
                let rough = 1.0 - m.roughness.clamp(0.0, 1.0);
                let sharp = rough * rough;
                let diffuse = l.diffuse + l.spec_albedo * (1.0 - sharp);
                color += weight.mul_elem(V3::from_array(m.radiance));
                color += weight.mul_elem(direct_light(inp, &ray, hit.t, ng, ns, diffuse));
                if depth < max_depth && sp < WHITTED_STACK && sharp > 0.0 {
                    stack[sp] = Pending {
                        ray: Ray::new(spawn_origin(&ray, hit.t, ng), mirrored()),
                        weight: weight.mul_elem(l.spec_albedo * sharp),
                        depth: depth + 1,
                    };
                    sp += 1;
                }
            }
            MaterialKind::Dielectric => {
                if depth < max_depth {
                    let cos_i = -ray.dir.dot(ns);
                    let eta = if front { m.ior } else { 1.0 / m.ior };
                    let f = fresnel_dielectric(cos_i, eta);
                    if sp < WHITTED_STACK {
                        let r = reflect(ray.dir, ns);
                        stack[sp] = Pending {
                            ray: Ray::new(spawn_origin(&ray, hit.t, ns), r),
                            weight: weight * f,
                            depth: depth + 1,
                        };
                        sp += 1;
                    }
                    if f < 1.0 && sp < WHITTED_STACK {
                        let t = refract(ray.dir, ns, cos_i, 1.0 / eta);
                        stack[sp] = Pending {
                            ray: Ray::new(spawn_origin(&ray, hit.t, -ns), t),
                            weight: weight.mul_elem(albedo) * (1.0 - f),
                            depth: depth + 1,
                        };
                        sp += 1;
                    }
                }
            }
            MaterialKind::Diffuse => {
                color += weight.mul_elem(direct_light(inp, &ray, hit.t, ng, ns, albedo));
            }
        }
    }
    color
}

/// The mean radiance of samples `sample_base .. sample_base + spp` of pixel (x, y). A
/// non-finite sample (which a valid scene never produces) is counted as black.
pub fn shade_pixel(inp: &ShadeInputs, x: u32, y: u32) -> [f32; 3] {
    let f = inp.frame;
    let mut sum = V3::zero();
    for s in 0..f.spp {
        let c = radiance(inp, primary_ray(f, x, y, f.sample_base + s));
        if c.is_finite() {
            sum += c;
        }
    }
    (sum / f.spp as f32).to_array()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_matches_known_values() {
        // Normal incidence on glass: ((1.5 − 1)/(1.5 + 1))² = 0.04.
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        // Grazing incidence reflects everything.
        assert!((fresnel_dielectric(0.0, 1.5) - 1.0).abs() < 1e-6);
        // From inside glass beyond the critical angle (41.8°): total internal reflection.
        assert_eq!(fresnel_dielectric(0.5, 1.0 / 1.5), 1.0);
    }

    #[test]
    fn refraction_obeys_snell() {
        let n = V3::new(0.0, 1.0, 0.0f32);
        let d = V3::new(0.6, -0.8, 0.0f32);
        let t = refract(d, n, 0.8, 1.0 / 1.5);
        assert!((t.x - 0.6 / 1.5).abs() < 1e-6, "sin θ_t = sin θ_i / 1.5: {t:?}");
        assert!(t.y < 0.0);
    }
}
