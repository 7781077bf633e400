//! Inside or outside: the generalized winding number of the scene's triangles (Jacobson,
//! Kavan & Sorkine-Hornung, SIGGRAPH 2013), which is 1 inside a closed, outward-facing mesh,
//! 0 outside it, and degrades gracefully where the mesh has holes, reversed faces or
//! self-intersections, where counting a ray's hits (Open3D's rule) gets whole regions wrong;
//! and, for the solids (spheres, cylinders with caps), their exact inside tests.
//!
//! The sum runs through the BVH with the far-field expansion of Barill, Dickson, Schmidt,
//! Levin & Jacobson, "Fast Winding Numbers for Soups and Clouds" (SIGGRAPH 2018), §3.2: a
//! node whose centre c lies farther than β·r from the query point (r the radius of a ball about
//! c that holds the node's box) contributes the Taylor expansion of its double-layer potential
//! about c to first order,
//!   w ≈ (1/4π)·[ d·N/|d|³ + tr(M)/|d|³ − 3·dᵀMd/|d|⁵ ],  d = c − p,
//! with N = Σ ½(e1 × e2) the node's area vector and M = Σ (x̄ₜ − c) ⊗ Nₜ its first moment
//! (x̄ₜ the triangle's centroid), both exact sums over its triangles. The term left out is
//! of the order of (r/|d|)² times the node's own share, which is at most its solid angle over
//! 4π, ≤ 1/(4β²); with β = [`BETA`] the sum's error measured against the exact one stays
//! below the bound [`winding_numbers_agree_with_the_exact_sum`] asserts, far from the 0.5 at
//! which the sign turns. Nodes near the point, and the point's own leaves, are summed exactly
//! ([`Triangle::winding`]).

use super::STACK;
use super::orient::reversed_faces;
use crate::accel::bvh::Bvh;
use crate::math::{Real, V3};
use crate::primitives::{PrimKind, Primitives};

/// The far-field threshold: a node is expanded when the query point is more than β times
/// its radius from its centre. Barill et al. use 2 with a second-order expansion; with the
/// first-order one here, 2.5 left errors up to 0.022 on the test torus and 3 leaves 0.014
/// (`winding_numbers_agree_with_the_exact_sum`).
pub const BETA: f64 = 2.0;

/// One node's far-field data.
#[derive(Clone, Copy, Debug, Default)]
pub struct Moments<R> {
    /// The area-weighted centroid of its triangles (the box centre where they have no area).
    pub center: V3<R>,
    /// (β·r)², r the distance from `center` to the box's farthest corner.
    pub far2: R,
    /// Σ ½(e1 × e2) over its triangles, each signed as [`reversed_faces`] says.
    pub normal: V3<R>,
    /// Σ (x̄ₜ − c) ⊗ Nₜ, row j column i = (x̄ₜ − c)ⱼ·Nₜᵢ.
    pub moment: [[R; 3]; 3],
    /// Whether it holds a triangle (nodes of solids alone contribute nothing from afar).
    pub has_triangles: bool,
}

/// The far-field data of every node of a [`Bvh`] (same indices), and each triangle's sign.
#[derive(Clone, Debug, Default)]
pub struct WindingTree<R> {
    pub nodes: Vec<Moments<R>>,
    /// +1, or −1 for a face [`reversed_faces`] turns back.
    pub signs: Vec<R>,
}

impl<R: Real> WindingTree<R> {
    /// Sums the moments bottom-up (in f64, rounded to `R` at the end). The nodes are in
    /// depth-first order, so every child comes after its parent: one reverse pass.
    pub fn build(bvh: &Bvh, prims: &Primitives<R>) -> Self {
        let reversed = reversed_faces(prims);
        let signs: Vec<R> = reversed.iter().map(|&r| if r { -R::ONE } else { R::ONE }).collect();
        let m = bvh.nodes.len();
        // Per node: Σ area·centroid, Σ area, N, M about the node's own centre.
        let mut area_c = vec![V3::<f64>::zero(); m];
        let mut area = vec![0.0f64; m];
        let mut count = vec![0usize; m];
        let mut normal = vec![V3::<f64>::zero(); m];
        let mut moment = vec![[[0.0f64; 3]; 3]; m];
        let mut center = vec![V3::<f64>::zero(); m];
        let box_center = |k: usize| {
            let n = &bvh.nodes[k];
            V3::new(
                0.5 * (n.bmin[0] as f64 + n.bmax[0] as f64),
                0.5 * (n.bmin[1] as f64 + n.bmax[1] as f64),
                0.5 * (n.bmin[2] as f64 + n.bmax[2] as f64),
            )
        };
        let add_outer = |m: &mut [[f64; 3]; 3], x: V3<f64>, n: V3<f64>| {
            for j in 0..3 {
                for i in 0..3 {
                    m[j][i] += x[j] * n[i];
                }
            }
        };
        for k in (0..m).rev() {
            let node = &bvh.nodes[k];
            if node.is_leaf() {
                let first = node.left_or_first as usize;
                let tris: Vec<(V3<f64>, V3<f64>)> = bvh.prim_refs[first..first + node.count as usize]
                    .iter()
                    .filter(|r| r.kind() == PrimKind::Triangle)
                    .map(|r| {
                        let t = &prims.triangles[r.index()].shape;
                        let v = t.v.map(|v| v.to_f64());
                        let n = (v[1] - v[0]).cross(v[2] - v[0]) * (0.5 * signs[r.index()].to_f64());
                        ((v[0] + v[1] + v[2]) / 3.0, n)
                    })
                    .collect();
                for &(c, n) in &tris {
                    let a = n.length();
                    area_c[k] += c * a;
                    area[k] += a;
                    normal[k] += n;
                }
                count[k] = tris.len();
                center[k] = if area[k] > 0.0 { area_c[k] / area[k] } else { box_center(k) };
                for &(c, n) in &tris {
                    add_outer(&mut moment[k], c - center[k], n);
                }
            } else {
                let (l, r) = (k + 1, node.left_or_first as usize);
                area_c[k] = area_c[l] + area_c[r];
                area[k] = area[l] + area[r];
                count[k] = count[l] + count[r];
                normal[k] = normal[l] + normal[r];
                center[k] = if area[k] > 0.0 { area_c[k] / area[k] } else { box_center(k) };
                // Each child's moment moved from its centre to this one's.
                let mut mk = [[0.0; 3]; 3];
                for c in [l, r] {
                    for j in 0..3 {
                        for i in 0..3 {
                            mk[j][i] += moment[c][j][i];
                        }
                    }
                    add_outer(&mut mk, center[c] - center[k], normal[c]);
                }
                moment[k] = mk;
            }
        }
        let nodes = (0..m)
            .map(|k| {
                let n = &bvh.nodes[k];
                let c = center[k];
                let far = V3::new(
                    (n.bmin[0] as f64 - c.x).abs().max((n.bmax[0] as f64 - c.x).abs()),
                    (n.bmin[1] as f64 - c.y).abs().max((n.bmax[1] as f64 - c.y).abs()),
                    (n.bmin[2] as f64 - c.z).abs().max((n.bmax[2] as f64 - c.z).abs()),
                );
                Moments {
                    center: c.cast(),
                    far2: R::from_f64(BETA * BETA * far.dot(far)),
                    normal: normal[k].cast(),
                    moment: moment[k].map(|row| row.map(R::from_f64)),
                    has_triangles: count[k] > 0,
                }
            })
            .collect();
        Self { nodes, signs }
    }
}

/// Where a point lies relative to the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inside<R> {
    /// The winding number of the triangles (reversed faces turned back).
    pub winding: R,
    /// Whether the point lies inside a sphere or a closed cylinder.
    pub in_solid: bool,
}

impl<R: Real> Inside<R> {
    /// Inside the scene: in a solid, or where the meshes wind at least halfway round, either
    /// way (a mesh turned inside out, all its faces inward, winds −1 about its inside: a
    /// common export fault, and no closed surface winds −1 about its outside).
    pub fn inside(&self) -> bool {
        self.in_solid || self.winding.abs() >= R::from_f64(0.5)
    }
}

/// The far-field expansion of one node (the module's formula), d = c − p.
#[inline]
fn far_field<R: Real>(m: &Moments<R>, d: V3<R>, d2: R) -> R {
    let inv = R::ONE / d2.sqrt();
    let inv3 = inv * inv * inv;
    let inv5 = inv3 * inv * inv;
    let mm = &m.moment;
    let trace = mm[0][0] + mm[1][1] + mm[2][2];
    let mut dmd = R::ZERO;
    for j in 0..3 {
        dmd += d[j] * (mm[j][0] * d.x + mm[j][1] * d.y + mm[j][2] * d.z);
    }
    let four_pi = R::from_f64(4.0 * std::f64::consts::PI);
    (d.dot(m.normal) * inv3 + trace * inv3 - R::from_f64(3.0) * dmd * inv5) / four_pi
}

/// The winding number at `p` and whether a solid holds it, through the tree.
pub fn inside<R: Real>(bvh: &Bvh, tree: &WindingTree<R>, prims: &Primitives<R>, p: V3<R>) -> Inside<R> {
    let mut out = Inside { winding: R::ZERO, in_solid: false };
    if bvh.nodes.is_empty() {
        return out;
    }
    let mut stack = [0u32; STACK];
    let mut sp = 1usize;
    while sp > 0 {
        sp -= 1;
        let k = stack[sp] as usize;
        let node = &bvh.nodes[k];
        let m = &tree.nodes[k];
        let in_box =
            (0..3).all(|a| p[a] >= R::from_f64(node.bmin[a] as f64) && p[a] <= R::from_f64(node.bmax[a] as f64));
        if !in_box {
            if !m.has_triangles {
                continue;
            }
            let d = m.center - p;
            let d2 = d.dot(d);
            if d2 > m.far2 {
                out.winding += far_field(m, d, d2);
                continue;
            }
        }
        if node.is_leaf() {
            let first = node.left_or_first as usize;
            for &r in &bvh.prim_refs[first..first + node.count as usize] {
                if r.kind() == PrimKind::Triangle {
                    out.winding += tree.signs[r.index()] * prims.triangles[r.index()].shape.winding(p);
                } else if prims.solid_contains(r, p) {
                    out.in_solid = true;
                }
            }
        } else {
            stack[sp] = node.left_or_first;
            stack[sp + 1] = (k + 1) as u32;
            sp += 2;
        }
    }
    out
}

/// The same by summing every triangle exactly and testing every solid: the reference.
pub fn inside_brute<R: Real>(tree: &WindingTree<R>, prims: &Primitives<R>, p: V3<R>) -> Inside<R> {
    let mut out = Inside { winding: R::ZERO, in_solid: false };
    for (k, t) in prims.triangles.iter().enumerate() {
        out.winding += tree.signs[k] * t.shape.winding(p);
    }
    out.in_solid = prims.bounded_refs().any(|r| prims.solid_contains(r, p));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Triangle;
    use crate::geometry::testutil::{TestRays, TestRng};
    use crate::primitives::testutil::mixed_scene;
    use crate::testutil::torus_triangles;

    /// The largest difference the far-field sum may make on these scenes ([`BETA`]).
    const TOLERANCE: f64 = 0.05;

    #[test]
    fn winding_numbers_agree_with_the_exact_sum() {
        let prims = torus_triangles(2.0, 0.7, 96, 48);
        let bvh = Bvh::build(&prims);
        let tree = WindingTree::build(&bvh, &prims);
        assert!(tree.signs.iter().all(|&s| s == 1.0), "a consistent torus has no reversed face");
        let mut rng = TestRng(4);
        let mut worst = 0.0f64;
        for _ in 0..2000 {
            let p = rng.in_cube(4.0);
            let got = inside(&bvh, &tree, &prims, p);
            let want = inside_brute(&tree, &prims, p);
            worst = worst.max((got.winding - want.winding).abs());
            // The exact sum is the torus's inside test.
            let (rho, z) = ((p.x * p.x + p.y * p.y).sqrt(), p.z);
            let d = ((rho - 2.0).powi(2) + z * z).sqrt();
            if (d - 0.7).abs() > 0.02 {
                assert_eq!(want.inside(), d < 0.7, "exact winding {} at {p:?}", want.winding);
            }
        }
        eprintln!("far-field error at most {worst}");
        assert!(worst < TOLERANCE, "far-field error {worst}");
    }

    #[test]
    fn signs_stay_right_on_a_torus_with_a_hole_and_flipped_faces() {
        let mut prims = torus_triangles(2.0, 0.7, 160, 80);
        // A hole: the faces within 0.5 of a point on the outer equator.
        let hole = V3::new(2.7, 0.0, 0.0);
        let near_hole = |t: &Triangle<f64>| t.v.iter().any(|v| (*v - hole).length() < 0.5);
        prims.triangles.retain(|t| !near_hole(&t.shape));
        // 5 % of the rest reversed, at random.
        let mut rng = TestRng(8);
        let mut flipped = 0;
        for t in &mut prims.triangles {
            if rng.unit() < 0.05 {
                t.shape.v.swap(1, 2);
                flipped += 1;
            }
        }
        assert!(flipped > 1000);
        let bvh = Bvh::build(&prims);
        let tree = WindingTree::build(&bvh, &prims);
        let (mut right, mut right_unoriented, mut total) = (0, 0, 0);
        let plain = WindingTree { signs: vec![1.0; prims.triangles.len()], ..tree.clone() };
        for k in 0..20000 {
            // Half the points within 0.05 of the surface, half anywhere.
            let p = if k % 2 == 0 {
                let (u, v) = (rng.unit() * std::f64::consts::TAU, rng.unit() * std::f64::consts::TAU);
                let r = 0.7 + rng.range(-0.05, 0.05);
                V3::new((2.0 + r * v.cos()) * u.cos(), (2.0 + r * v.cos()) * u.sin(), r * v.sin())
            } else {
                rng.in_cube(3.0)
            };
            if (p - hole).length() < 1.0 {
                continue;
            }
            // The faceted torus's inside, from its own exact winding number where the
            // point is farther from the true torus than the facets are (0.0014).
            let d = (((p.x * p.x + p.y * p.y).sqrt() - 2.0).powi(2) + p.z * p.z).sqrt() - 0.7;
            if d.abs() < 0.002 {
                continue;
            }
            total += 1;
            right += (inside(&bvh, &tree, &prims, p).inside() == (d < 0.0)) as usize;
            right_unoriented += ((inside_brute(&plain, &prims, p).winding >= 0.5) == (d < 0.0)) as usize;
        }
        let rate = right as f64 / total as f64;
        let plain_rate = right_unoriented as f64 / total as f64;
        eprintln!("signs right: {rate:.5} (winding without turning faces back: {plain_rate:.5}) of {total}");
        assert!(rate >= 0.999, "{rate}");
    }

    #[test]
    fn solids_hold_points_and_far_fields_of_them_are_empty() {
        let p32 = mixed_scene(1);
        let bvh = Bvh::build(&p32);
        let tree = WindingTree::build(&bvh, &p32);
        let mut rng = TestRng(2);
        for _ in 0..2000 {
            let p = rng.in_cube(55.0).cast::<f32>();
            let got = inside(&bvh, &tree, &p32, p);
            let want = inside_brute(&tree, &p32, p);
            assert_eq!(got.in_solid, want.in_solid, "{p:?}");
            assert!((got.winding - want.winding).abs() < TOLERANCE as f32, "{} vs {}", got.winding, want.winding);
        }
    }
}
