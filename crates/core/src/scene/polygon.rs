//! Planar polygons: validation and ear-clipping triangulation.
//!
//! A `polygon` object is a list of vertices in 3D. It must be planar and simple (its edges
//! meet only at shared vertices), and may be convex or concave. It is cut into n − 2
//! triangles by ear clipping in the 2D projection onto its plane; every triangle keeps the
//! input's winding, so its front normal (v1 − v0) × (v2 − v0) points the way of the
//! polygon's Newell normal.

use crate::geometry::Triangle;
use crate::math::V3;

/// The most vertices a polygon may have (ear clipping is quadratic or worse); larger
/// shapes belong in a mesh file.
pub const MAX_POLYGON_VERTICES: usize = 4096;

/// Validates a polygon and triangulates it. See the module documentation for the rules.
pub fn triangulate(vertices: &[V3<f64>]) -> Result<Vec<Triangle<f64>>, String> {
    let n = vertices.len();
    if n < 3 {
        return Err(format!("a polygon needs at least 3 vertices, got {n}"));
    }
    if n > MAX_POLYGON_VERTICES {
        return Err(format!("a polygon may have at most {MAX_POLYGON_VERTICES} vertices, got {n}; use a mesh file"));
    }
    if let Some(i) = vertices.iter().position(|v| !v.is_finite()) {
        return Err(format!("vertex {i} must be finite, got {}", fmt_v(vertices[i])));
    }
    for i in 0..n {
        let j = (i + 1) % n;
        if vertices[i] == vertices[j] {
            return Err(format!("vertices {i} and {j} are the same point {}", fmt_v(vertices[i])));
        }
    }

    let diameter = diameter(vertices);
    if !diameter.is_finite() {
        return Err("the polygon is too large (its size overflows)".into());
    }
    let threshold = 1e-12 * diameter * diameter;
    let newell = newell_normal(vertices);
    // A polygon whose Newell normal vanishes is either collinear or has zero net area (a
    // symmetric bow-tie): in the latter case its points still span a plane, which is used to
    // find the crossing edges.
    let zero_area = newell.length().is_nan() || newell.length() <= threshold;
    let normal = if zero_area {
        let span = spanning_normal(vertices);
        if span.length().is_nan() || span.length() <= threshold {
            return Err("degenerate polygon: its vertices are collinear (zero area)".into());
        }
        span
    } else {
        newell
    };
    let unit = normal / normal.length();
    let centroid = vertices.iter().fold(V3::zero(), |a, &v| a + v) / n as f64;
    let tol = 1e-6 * diameter;
    for (i, &v) in vertices.iter().enumerate() {
        let d = (v - centroid).dot(unit);
        if d.abs() > tol {
            return Err(format!(
                "the polygon is not planar: vertex {i} {} is {:.3e} from its plane (tolerance {:.3e})",
                fmt_v(v),
                d.abs(),
                tol
            ));
        }
    }

    // Project onto the plane of the two axes other than the normal's largest: with
    // (u, v) = (k+1, k+2) mod 3 the projected signed area has the sign of normal[k].
    let k = normal.max_abs_axis();
    let (ku, kv) = ((k + 1) % 3, (k + 2) % 3);
    let orient = if normal[k] > 0.0 { 1.0 } else { -1.0 };
    // Centre the 2D points on the centroid to keep the predicates well conditioned, and
    // flip v for clockwise input so the ear clipper always sees a counter-clockwise polygon.
    let pts: Vec<[f64; 2]> = vertices.iter().map(|p| [p[ku] - centroid[ku], orient * (p[kv] - centroid[kv])]).collect();

    check_simple(&pts)?;
    if zero_area {
        return Err("degenerate polygon: its signed area is zero".into());
    }

    let ids = ear_clip(&pts)
        .ok_or_else(|| "the polygon could not be triangulated (it is numerically degenerate)".to_string())?;
    Ok(ids.into_iter().map(|[a, b, c]| Triangle { v: [vertices[a], vertices[b], vertices[c]] }).collect())
}

fn fmt_v(v: V3<f64>) -> String {
    format!("({}, {}, {})", v.x, v.y, v.z)
}

/// Largest distance between two vertices.
fn diameter(vertices: &[V3<f64>]) -> f64 {
    let mut d2: f64 = 0.0;
    for (i, &a) in vertices.iter().enumerate() {
        for &b in &vertices[i + 1..] {
            d2 = d2.max((b - a).length_squared());
        }
    }
    d2.sqrt()
}

/// Newell's normal: twice the polygon's vector area, computed about the first vertex.
fn newell_normal(vertices: &[V3<f64>]) -> V3<f64> {
    let o = vertices[0];
    let n = vertices.len();
    let mut sum = V3::zero();
    for i in 1..n - 1 {
        sum += (vertices[i] - o).cross(vertices[i + 1] - o);
    }
    sum
}

/// The largest (v_far − v0) × (v_i − v0), v_far the vertex farthest from v0: non-zero unless
/// all vertices are collinear.
fn spanning_normal(vertices: &[V3<f64>]) -> V3<f64> {
    let o = vertices[0];
    let far = vertices
        .iter()
        .map(|&v| v - o)
        .fold(V3::zero(), |a, d| if d.length_squared() > a.length_squared() { d } else { a });
    vertices
        .iter()
        .map(|&v| far.cross(v - o))
        .fold(V3::zero(), |a, c| if c.length_squared() > a.length_squared() { c } else { a })
}

/// Twice the signed area of (a, b, c): > 0 when counter-clockwise.
fn orient2d(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Whether p lies within the bounding box of segment ab (used once p is known collinear).
fn in_box(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> bool {
    p[0] >= a[0].min(b[0]) && p[0] <= a[0].max(b[0]) && p[1] >= a[1].min(b[1]) && p[1] <= a[1].max(b[1])
}

/// Whether closed segments ab and cd share a point.
fn segments_intersect(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
    let d1 = orient2d(c, d, a);
    let d2 = orient2d(c, d, b);
    let d3 = orient2d(a, b, c);
    let d4 = orient2d(a, b, d);
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0)) && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0)) {
        return true;
    }
    (d1 == 0.0 && in_box(c, d, a))
        || (d2 == 0.0 && in_box(c, d, b))
        || (d3 == 0.0 && in_box(a, b, c))
        || (d4 == 0.0 && in_box(a, b, d))
}

/// Rejects polygons whose edges cross or touch anywhere but at the vertex two adjacent
/// edges share, and adjacent edges that fold back over each other.
fn check_simple(p: &[[f64; 2]]) -> Result<(), String> {
    let n = p.len();
    for i in 0..n {
        let (a, b) = (p[i], p[(i + 1) % n]);
        // Adjacent edge i+1 folding back onto edge i (a spike of zero width).
        let c = p[(i + 2) % n];
        if orient2d(a, b, c) == 0.0 {
            let back = (b[0] - a[0]) * (c[0] - b[0]) + (b[1] - a[1]) * (c[1] - b[1]);
            if back < 0.0 {
                return Err(format!(
                    "the polygon is self-intersecting: edges {i} and {} fold back over each other",
                    (i + 1) % n
                ));
            }
        }
        for j in i + 2..n {
            if i == 0 && j == n - 1 {
                continue; // edges n-1 and 0 are adjacent
            }
            let (c, d) = (p[j], p[(j + 1) % n]);
            if segments_intersect(a, b, c, d) {
                return Err(format!("the polygon is self-intersecting: edges {i} and {j} cross"));
            }
        }
    }
    Ok(())
}

/// Ear clipping of a simple counter-clockwise polygon: n − 2 index triples, each
/// counter-clockwise like the input. None if no ear can be found (numerical trouble).
fn ear_clip(p: &[[f64; 2]]) -> Option<Vec<[usize; 3]>> {
    let n = p.len();
    let mut idx: Vec<usize> = (0..n).collect();
    let mut out = Vec::with_capacity(n - 2);
    let mut start = 0;
    while idx.len() > 3 {
        let m = idx.len();
        let mut found = None;
        for step in 0..m {
            let i = (start + step) % m;
            let (a, b, c) = (idx[(i + m - 1) % m], idx[i], idx[(i + 1) % m]);
            if is_ear(p, &idx, a, b, c) {
                found = Some((i, [a, b, c]));
                break;
            }
        }
        let (i, tri) = found?;
        out.push(tri);
        idx.remove(i);
        // Continue from the previous vertex: the neighbours of a clipped ear are the most
        // likely next ears, which keeps the usual cost near O(n²).
        start = (i + idx.len() - 1) % idx.len();
    }
    let tri = [idx[0], idx[1], idx[2]];
    if orient2d(p[tri[0]], p[tri[1]], p[tri[2]]) <= 0.0 {
        return None;
    }
    out.push(tri);
    Some(out)
}

/// b is an ear if the corner (a, b, c) is strictly convex and no other remaining vertex
/// lies inside or on the triangle (a vertex on the diagonal ac would make it cut the
/// polygon).
fn is_ear(p: &[[f64; 2]], idx: &[usize], a: usize, b: usize, c: usize) -> bool {
    let (pa, pb, pc) = (p[a], p[b], p[c]);
    if orient2d(pa, pb, pc) <= 0.0 {
        return false;
    }
    idx.iter().all(|&q| {
        if q == a || q == b || q == c {
            return true;
        }
        let pq = p[q];
        if pq == pa || pq == pb || pq == pc {
            return true;
        }
        !(orient2d(pa, pb, pq) >= 0.0 && orient2d(pb, pc, pq) >= 0.0 && orient2d(pc, pa, pq) >= 0.0)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> V3<f64> {
        V3::new(x, y, z)
    }

    fn area(t: &Triangle<f64>) -> f64 {
        0.5 * t.face_normal().length()
    }

    fn contains(t: &Triangle<f64>, p: V3<f64>) -> bool {
        let n = t.face_normal();
        (0..3).all(|i| (t.v[(i + 1) % 3] - t.v[i]).cross(p - t.v[i]).dot(n) > 0.0)
    }

    #[test]
    fn square_gives_two_triangles_of_total_area() {
        let sq = [v(0.0, 0.0, 0.0), v(2.0, 0.0, 0.0), v(2.0, 2.0, 0.0), v(0.0, 2.0, 0.0)];
        let tris = triangulate(&sq).unwrap();
        assert_eq!(tris.len(), 2);
        let a: f64 = tris.iter().map(area).sum();
        assert!((a - 4.0).abs() < 1e-12, "{a}");
        for t in &tris {
            assert!(t.face_normal().z > 0.0, "winding kept: {t:?}");
        }
    }

    #[test]
    fn clockwise_input_keeps_its_winding() {
        // In the y = 1 plane, wound so that the Newell normal is −y.
        let sq = [v(0.0, 1.0, 0.0), v(1.0, 1.0, 0.0), v(1.0, 1.0, 1.0), v(0.0, 1.0, 1.0)];
        let n = newell_normal(&sq);
        assert!(n.y < 0.0);
        for t in triangulate(&sq).unwrap() {
            assert!(t.face_normal().y < 0.0);
        }
    }

    #[test]
    fn concave_l_hexagon() {
        // An L: the 2×2 square minus its top-right 1×1 quadrant, in the x = 3 plane.
        let yz = [(0.0, 0.0), (2.0, 0.0), (2.0, 1.0), (1.0, 1.0), (1.0, 2.0), (0.0, 2.0)];
        let poly: Vec<_> = yz.iter().map(|&(y, z)| v(3.0, y, z)).collect();
        let tris = triangulate(&poly).unwrap();
        assert_eq!(tris.len(), 4);
        let a: f64 = tris.iter().map(area).sum();
        assert!((a - 3.0).abs() < 1e-12, "{a}");
        let notch = v(3.0, 1.5, 1.5);
        for t in &tris {
            assert!(!contains(t, notch), "{t:?} covers the notch");
            assert!(t.face_normal().x > 0.0);
        }
    }

    #[test]
    fn star_is_triangulated() {
        let mut pts = Vec::new();
        for i in 0..10 {
            let a = i as f64 * std::f64::consts::PI / 5.0;
            let r = if i % 2 == 0 { 2.0 } else { 0.8 };
            pts.push(v(r * a.cos(), 0.5, r * a.sin()));
        }
        let tris = triangulate(&pts).unwrap();
        assert_eq!(tris.len(), 8);
        let want = 0.5 * newell_normal(&pts).length();
        let a: f64 = tris.iter().map(area).sum();
        assert!((a - want).abs() < 1e-12);
    }

    #[test]
    fn collinear_point_on_an_edge_is_fine() {
        let p = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(2.0, 0.0, 0.0), v(2.0, 2.0, 0.0), v(0.0, 2.0, 0.0)];
        let tris = triangulate(&p).unwrap();
        assert_eq!(tris.len(), 3);
        for t in &tris {
            assert!(area(t) > 1e-9);
        }
    }

    #[test]
    fn bow_tie_is_rejected() {
        let p = [v(0.0, 0.0, 0.0), v(1.0, 1.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)];
        let e = triangulate(&p).unwrap_err();
        assert!(e.contains("self-intersecting"), "{e}");
    }

    #[test]
    fn non_planar_is_rejected() {
        let p = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(1.0, 1.0, 0.1), v(0.0, 1.0, 0.0)];
        let e = triangulate(&p).unwrap_err();
        assert!(e.contains("not planar"), "{e}");
    }

    #[test]
    fn collinear_is_rejected() {
        let p = [v(0.0, 0.0, 0.0), v(1.0, 1.0, 1.0), v(2.0, 2.0, 2.0)];
        let e = triangulate(&p).unwrap_err();
        assert!(e.contains("collinear"), "{e}");
    }

    #[test]
    fn other_bad_inputs() {
        assert!(triangulate(&[v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0)]).unwrap_err().contains("at least 3"));
        let e = triangulate(&[v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)]).unwrap_err();
        assert!(e.contains("same point"), "{e}");
        let e = triangulate(&[v(0.0, 0.0, 0.0), v(f64::NAN, 0.0, 0.0), v(0.0, 1.0, 0.0)]).unwrap_err();
        assert!(e.contains("finite"), "{e}");
        // A spike folding back along itself.
        let e = triangulate(&[v(0.0, 0.0, 0.0), v(2.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)]).unwrap_err();
        assert!(e.contains("self-intersecting"), "{e}");
        // Two vertices at the same place (not consecutive): edges touch.
        let e = triangulate(&[
            v(0.0, 0.0, 0.0),
            v(2.0, 0.0, 0.0),
            v(1.0, 1.0, 0.0),
            v(2.0, 2.0, 0.0),
            v(0.0, 2.0, 0.0),
            v(1.0, 1.0, 0.0),
        ])
        .unwrap_err();
        assert!(e.contains("self-intersecting"), "{e}");
    }
}
