//! The scene flattened into per-kind primitive arrays: the layout the BVH indexes and the GPU
//! reads (see [`crate::layout`]). Polygons and meshes become triangles here.
//!
//! A primitive is named by a [`PrimRef`], a `u32` with the kind in its top two bits. Its order
//! (spheres < cylinders < triangles < planes) breaks ties between hits at the same `t`, so the
//! BVH, the brute-force loop and the GPU all return the same primitive.

use crate::geometry::{Cylinder, Part, Plane, Roots, Shape, Sphere, Triangle};
use crate::math::{Ray, Real, V3};
use crate::scene::{Geometry, Scene};

/// Which scene object, which triangle inside it, and which material a primitive carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Tag {
    /// Index in the scene's `[[objects]]`.
    pub object: u32,
    /// Face: the triangle's index inside its polygon or mesh, else 0 (the `prim` column of
    /// `strahl trace`'s output).
    pub face: u32,
    pub material: u32,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tagged<T> {
    pub shape: T,
    pub tag: Tag,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum PrimKind {
    Sphere = 0,
    Cylinder = 1,
    Triangle = 2,
    Plane = 3,
}

/// A primitive reference: kind in bits 30–31, index in its kind's array in bits 0–29.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct PrimRef(pub u32);

impl PrimRef {
    pub const INDEX_BITS: u32 = 30;
    pub const MAX_INDEX: u32 = (1 << Self::INDEX_BITS) - 1;
    pub fn new(kind: PrimKind, index: usize) -> Self {
        debug_assert!(index as u64 <= Self::MAX_INDEX as u64);
        Self(((kind as u32) << Self::INDEX_BITS) | index as u32)
    }
    pub fn kind(self) -> PrimKind {
        match self.0 >> Self::INDEX_BITS {
            0 => PrimKind::Sphere,
            1 => PrimKind::Cylinder,
            2 => PrimKind::Triangle,
            _ => PrimKind::Plane,
        }
    }
    pub fn index(self) -> usize {
        (self.0 & Self::MAX_INDEX) as usize
    }
}

/// One intersection, resolved: where, which way the surface faces, and what was hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit<R> {
    pub t: R,
    /// Unit geometric normal of the front face (outward for solids).
    pub normal: V3<R>,
    pub prim_ref: PrimRef,
    pub part: Part,
    pub tag: Tag,
    /// The ray enters a solid or meets a surface's front face (d·n < 0).
    pub enter: bool,
}

/// The best hit so far in a nearest-hit search, with the tie rule shared by every traversal.
#[derive(Clone, Copy, Debug)]
pub struct Nearest<R> {
    pub t: R,
    pub prim_ref: PrimRef,
    pub part: Part,
    pub found: bool,
}

impl<R: Real> Nearest<R> {
    pub fn new(tmax: R) -> Self {
        Self { t: tmax, prim_ref: PrimRef(u32::MAX), part: Part::Surface, found: false }
    }
    /// Upper bound to pass to `roots`: roots at exactly `t` must still be seen for the tie
    /// rule, so the bound is the next representable value above it.
    #[inline]
    pub fn search_bound(&self) -> R {
        if self.found { next_up(self.t) } else { self.t }
    }
    /// Keeps the smaller `t`; at equal `t`, the smaller [`PrimRef`].
    #[inline]
    pub fn offer(&mut self, t: R, prim: PrimRef, part: Part) {
        if t < self.t || (t == self.t && prim < self.prim_ref) {
            self.t = t;
            self.prim_ref = prim;
            self.part = part;
            self.found = true;
        }
    }
}

/// The next representable value above a finite `v` (the identity for ±∞).
pub fn next_up<R: Real>(v: R) -> R {
    let f = v.to_f64();
    if !f.is_finite() {
        return v;
    }
    if std::mem::size_of::<R>() == 4 { R::from_f64((f as f32).next_up() as f64) } else { R::from_f64(f.next_up()) }
}

#[derive(Clone, Debug, Default)]
pub struct Primitives<R> {
    pub spheres: Vec<Tagged<Sphere<R>>>,
    pub cylinders: Vec<Tagged<Cylinder<R>>>,
    pub triangles: Vec<Tagged<Triangle<R>>>,
    /// Unbounded: kept outside the BVH and tested for every ray.
    pub planes: Vec<Tagged<Plane<R>>>,
}

impl<R: Real> Primitives<R> {
    /// Flattens a scene, rounding its f64 geometry to `R`.
    pub fn from_scene(scene: &Scene) -> Self {
        let mut p = Self {
            spheres: Vec::new(),
            cylinders: Vec::new(),
            triangles: Vec::with_capacity(scene.triangle_count()),
            planes: Vec::new(),
        };
        for (i, obj) in scene.objects.iter().enumerate() {
            let tag = |face: usize| Tag { object: i as u32, face: face as u32, material: obj.material };
            match &obj.geometry {
                Geometry::Sphere(s) => p.spheres.push(Tagged { shape: s.cast(), tag: tag(0) }),
                Geometry::Cylinder(c) => p.cylinders.push(Tagged { shape: c.cast(), tag: tag(0) }),
                Geometry::Plane(pl) => {
                    let mut plane = pl.cast::<R>();
                    plane.normal = plane.normal.normalize();
                    p.planes.push(Tagged { shape: plane, tag: tag(0) })
                }
                Geometry::Triangle(t) => p.triangles.push(Tagged { shape: t.cast(), tag: tag(0) }),
                Geometry::Polygon { triangles, .. } => {
                    for (k, t) in triangles.iter().enumerate() {
                        p.triangles.push(Tagged { shape: t.cast(), tag: tag(k) });
                    }
                }
                Geometry::Mesh { triangles, materials, .. } => {
                    for (k, t) in triangles.iter().enumerate() {
                        // A glTF file's triangles carry their own materials.
                        let material = materials.get(k).copied().unwrap_or(obj.material);
                        p.triangles.push(Tagged { shape: t.cast(), tag: Tag { material, ..tag(k) } });
                    }
                }
            }
        }
        p
    }

    /// The same primitives rounded to another precision.
    pub fn cast<S: Real>(&self) -> Primitives<S> {
        fn each<T: Copy, U>(v: &[Tagged<T>], f: impl Fn(&T) -> U) -> Vec<Tagged<U>> {
            v.iter().map(|t| Tagged { shape: f(&t.shape), tag: t.tag }).collect()
        }
        Primitives {
            spheres: each(&self.spheres, |s| s.cast()),
            cylinders: each(&self.cylinders, |c| c.cast()),
            triangles: each(&self.triangles, |t| t.cast()),
            planes: each(&self.planes, |p| p.cast()),
        }
    }

    /// Bounded primitive `i` in the order of [`Self::bounded_refs`] (`i < bounded_count()`).
    pub fn bounded_ref(&self, i: usize) -> PrimRef {
        let (s, c) = (self.spheres.len(), self.cylinders.len());
        if i < s {
            PrimRef::new(PrimKind::Sphere, i)
        } else if i < s + c {
            PrimRef::new(PrimKind::Cylinder, i - s)
        } else {
            PrimRef::new(PrimKind::Triangle, i - s - c)
        }
    }

    /// Every bounded primitive, in [`PrimRef`] order: spheres, then cylinders, then triangles.
    pub fn bounded_refs(&self) -> impl Iterator<Item = PrimRef> + '_ {
        (0..self.bounded_count()).map(|i| self.bounded_ref(i))
    }

    pub fn plane_refs(&self) -> impl Iterator<Item = PrimRef> + '_ {
        (0..self.planes.len()).map(|i| PrimRef::new(PrimKind::Plane, i))
    }

    pub fn bounded_count(&self) -> usize {
        self.spheres.len() + self.cylinders.len() + self.triangles.len()
    }

    #[inline]
    pub fn tag(&self, r: PrimRef) -> Tag {
        let i = r.index();
        match r.kind() {
            PrimKind::Sphere => self.spheres[i].tag,
            PrimKind::Cylinder => self.cylinders[i].tag,
            PrimKind::Triangle => self.triangles[i].tag,
            PrimKind::Plane => self.planes[i].tag,
        }
    }

    /// The roots of one primitive in (tmin, tmax).
    #[inline]
    pub fn roots(&self, r: PrimRef, ray: &Ray<R>, tmin: R, tmax: R) -> Roots<R> {
        let i = r.index();
        match r.kind() {
            PrimKind::Sphere => self.spheres[i].shape.roots(ray, tmin, tmax),
            PrimKind::Cylinder => self.cylinders[i].shape.roots(ray, tmin, tmax),
            PrimKind::Triangle => self.triangles[i].shape.roots(ray, tmin, tmax),
            PrimKind::Plane => self.planes[i].shape.roots(ray, tmin, tmax),
        }
    }

    /// Bounds of a bounded primitive, in f64.
    pub fn bounds_f64(&self, r: PrimRef) -> (V3<f64>, V3<f64>) {
        let i = r.index();
        let b = match r.kind() {
            PrimKind::Sphere => self.spheres[i].shape.cast::<f64>().bounds(),
            PrimKind::Cylinder => self.cylinders[i].shape.cast::<f64>().bounds(),
            PrimKind::Triangle => self.triangles[i].shape.cast::<f64>().bounds(),
            PrimKind::Plane => None,
        };
        b.expect("planes are unbounded and never enter the BVH")
    }

    /// Resolves a root into a full hit record.
    pub fn hit(&self, r: PrimRef, ray: &Ray<R>, t: R, part: Part) -> Hit<R> {
        let i = r.index();
        let normal = match r.kind() {
            PrimKind::Sphere => self.spheres[i].shape.normal(ray, t, part),
            PrimKind::Cylinder => self.cylinders[i].shape.normal(ray, t, part),
            PrimKind::Triangle => self.triangles[i].shape.normal(ray, t, part),
            PrimKind::Plane => self.planes[i].shape.normal(ray, t, part),
        };
        Hit { t, normal, prim_ref: r, part, tag: self.tag(r), enter: ray.dir.dot(normal) < R::ZERO }
    }

    /// Offers every root of `r` below the current best to `best`.
    #[inline]
    pub fn offer_nearest(&self, r: PrimRef, ray: &Ray<R>, tmin: R, best: &mut Nearest<R>) {
        if let Some((t, part)) = self.roots(r, ray, tmin, best.search_bound()).first() {
            best.offer(t, r, part);
        }
    }

    /// The nearest hit by testing every primitive: the reference the BVH must reproduce.
    pub fn nearest_brute(&self, ray: &Ray<R>, tmin: R, tmax: R) -> Option<Hit<R>> {
        let mut best = Nearest::new(tmax);
        for r in self.bounded_refs().chain(self.plane_refs()) {
            self.offer_nearest(r, ray, tmin, &mut best);
        }
        best.found.then(|| self.hit(best.prim_ref, ray, best.t, best.part))
    }

    /// Every hit in (tmin, tmax) by testing every primitive, sorted by `t` then [`PrimRef`].
    pub fn all_brute(&self, ray: &Ray<R>, tmin: R, tmax: R) -> Vec<Hit<R>> {
        let mut hits = Vec::new();
        for r in self.bounded_refs().chain(self.plane_refs()) {
            self.collect_hits(r, ray, tmin, tmax, &mut hits);
        }
        sort_hits(&mut hits);
        hits
    }

    pub fn collect_hits(&self, r: PrimRef, ray: &Ray<R>, tmin: R, tmax: R, out: &mut Vec<Hit<R>>) {
        for (t, part) in self.roots(r, ray, tmin, tmax).iter() {
            out.push(self.hit(r, ray, t, part));
        }
    }
}

/// Orders hits along the ray; hits at equal `t` by [`PrimRef`], then by part.
pub fn sort_hits<R: Real>(hits: &mut [Hit<R>]) {
    hits.sort_by(|a, b| {
        a.t.partial_cmp(&b.t)
            .unwrap_or(std::cmp::Ordering::Equal)
            .then(a.prim_ref.cmp(&b.prim_ref))
            .then((a.part as u8).cmp(&(b.part as u8)))
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prim_refs_order_by_kind_then_index() {
        let a = PrimRef::new(PrimKind::Sphere, 5);
        let b = PrimRef::new(PrimKind::Cylinder, 0);
        let c = PrimRef::new(PrimKind::Triangle, PrimRef::MAX_INDEX as usize);
        assert!(a < b && b < c);
        assert_eq!((c.kind(), c.index()), (PrimKind::Triangle, PrimRef::MAX_INDEX as usize));
    }

    #[test]
    fn nearest_breaks_ties_by_prim_ref() {
        let mut n = Nearest::new(f32::INFINITY);
        let (p, q) = (PrimRef::new(PrimKind::Triangle, 9), PrimRef::new(PrimKind::Triangle, 2));
        n.offer(3.0, p, Part::Surface);
        assert_eq!(n.search_bound(), 3.0f32.next_up());
        n.offer(3.0, q, Part::Surface);
        assert_eq!(n.prim_ref, q);
        n.offer(3.0, p, Part::Surface);
        assert_eq!(n.prim_ref, q, "a larger ref at the same t never replaces a smaller one");
        n.offer(2.5, p, Part::Surface);
        assert_eq!((n.t, n.prim_ref), (2.5, p));
    }
}

/// Scenes the BVH tests walk.
#[doc(hidden)]
pub mod testutil {
    use super::{Primitives, Tag, Tagged};
    use crate::geometry::testutil::{TestRays, TestRng};
    use crate::geometry::{Cylinder, Plane, Sphere, Triangle};
    use crate::math::V3;

    /// A mixed scene: spheres, cylinders, triangles scattered in a 100-unit cube, one plane.
    pub fn mixed_scene(seed: u64) -> Primitives<f32> {
        let mut rng = TestRng(seed);
        let mut p = Primitives::<f64>::default();
        let tag = |o: usize| Tag { object: o as u32, face: 0, material: 0 };
        for i in 0..300 {
            p.spheres
                .push(Tagged { shape: Sphere { center: rng.in_cube(50.0), radius: rng.range(0.2, 3.0) }, tag: tag(i) });
        }
        for i in 0..300 {
            let p1 = rng.in_cube(50.0);
            let p2 = p1 + rng.unit_vector() * rng.range(0.5, 6.0);
            let caps = i % 2 == 0;
            p.cylinders
                .push(Tagged { shape: Cylinder { p1, p2, radius: rng.range(0.1, 1.5), caps }, tag: tag(300 + i) });
        }
        for i in 0..3000 {
            let c = rng.in_cube(50.0);
            p.triangles
                .push(Tagged { shape: Triangle { v: [0, 1, 2].map(|_| c + rng.in_cube(2.5)) }, tag: tag(600 + i) });
        }
        p.planes.push(Tagged {
            shape: Plane { point: V3::new(0.0, -60.0, 0.0), normal: V3::new(0.0, 1.0, 0.0) },
            tag: tag(4000),
        });
        p.cast()
    }
}
