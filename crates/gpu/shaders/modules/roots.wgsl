// Root lists and the stable quadratic: twin of crates/core/src/geometry/mod.rs.
#define_import_path strahl::roots

// n normalised, or fallback where n is zero or its squared length overflows (geometry::unit_or):
// no NaN leaves a normal.
fn unit_or(n: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let l2 = dot(n, n);
    if l2 > 0.0 && l2 <= 3.40282347e38 {
        return normalize(n);
    }
    return fallback;
}

// Up to four roots of one primitive, ascending in t.
struct Roots {
    t: array<f32, 4>,
    part: array<u32, 4>,
    len: u32,
}

fn roots_empty() -> Roots {
    return Roots(array<f32, 4>(0.0, 0.0, 0.0, 0.0), array<u32, 4>(0u, 0u, 0u, 0u), 0u);
}

// Adds a root if it lies strictly inside (tmin, tmax), keeping the list sorted.
fn roots_push(r: ptr<function, Roots>, t: f32, part: u32, tmin: f32, tmax: f32) {
    if !(t > tmin && t < tmax) {
        return;
    }
    var i = (*r).len;
    while i > 0u && (*r).t[i - 1u] > t {
        (*r).t[i] = (*r).t[i - 1u];
        (*r).part[i] = (*r).part[i - 1u];
        i -= 1u;
    }
    (*r).t[i] = t;
    (*r).part[i] = part;
    (*r).len += 1u;
}

fn sign_nonzero(v: f32) -> f32 {
    return select(1.0, -1.0, v < 0.0);
}

// Real roots of a t^2 + 2 beta t + c = 0 given the discriminant disc = beta^2 - a c in a
// non-cancelling form: q = -(beta + sign(beta) sqrt(disc)), t1 = q / a, t2 = c / q
// (Numerical Recipes 5.6; Ray Tracing Gems ch. 7). Returns (t_lo, t_hi, 1) or (0, 0, 0).
fn stable_quadratic(a: f32, beta: f32, c: f32, disc: f32) -> vec3<f32> {
    if !(disc >= 0.0) || a == 0.0 {
        return vec3<f32>(0.0, 0.0, 0.0);
    }
    let q = -(beta + sign_nonzero(beta) * sqrt(disc));
    if q == 0.0 {
        return vec3<f32>(0.0, 0.0, 1.0);
    }
    let t1 = q / a;
    let t2 = c / q;
    if t1 <= t2 {
        return vec3<f32>(t1, t2, 1.0);
    }
    return vec3<f32>(t2, t1, 1.0);
}
