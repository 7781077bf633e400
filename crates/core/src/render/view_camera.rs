//! The interactive camera of `strahl view` and the web page: the scene file's pinhole camera,
//! moved by orbit, pan, zoom and fly. It keeps the file's up direction as the world's up, so
//! the horizon stays level.

use crate::math::V3;
use crate::scene::Camera;

/// The closest the view direction may come to the up axis when orbiting (radians).
const POLE_MARGIN: f64 = 0.01;

#[derive(Clone, Debug, PartialEq)]
pub struct ViewCamera {
    pub eye: V3<f64>,
    /// The point orbited around and zoomed towards (the file's `look_at` at first).
    pub target: V3<f64>,
    /// World up: the file's `up`, kept as written so that the untouched camera gives
    /// exactly the frame `strahl render` uses.
    pub up: V3<f64>,
    /// Vertical field of view in degrees.
    pub fov_y: f64,
}

/// `v` rotated by `angle` radians about the unit axis `k` (Rodrigues).
fn rotate(v: V3<f64>, k: V3<f64>, angle: f64) -> V3<f64> {
    let (s, c) = angle.sin_cos();
    v * c + k.cross(v) * s + k * (k.dot(v) * (1.0 - c))
}

impl ViewCamera {
    pub fn from_scene(c: &Camera) -> Self {
        Self { eye: c.eye, target: c.look_at, up: c.up, fov_y: c.fov_y }
    }

    /// The camera as the renderers take it.
    pub fn to_camera(&self) -> Camera {
        Camera { eye: self.eye, look_at: self.target, up: self.up, fov_y: self.fov_y }
    }

    pub fn distance(&self) -> f64 {
        (self.target - self.eye).length()
    }

    /// (forward, right, up) unit vectors of the view, as `render::camera::frame` forms them.
    pub fn basis(&self) -> (V3<f64>, V3<f64>, V3<f64>) {
        let forward = (self.target - self.eye).normalize();
        let right = self.up.cross(forward).normalize();
        (forward, right, forward.cross(right))
    }

    /// Turns the eye about the target: `yaw` radians about the world up (positive: the
    /// view swings to the right), `pitch` radians about the view's right axis (positive: the
    /// eye rises). The eye never passes over a pole.
    pub fn orbit(&mut self, yaw: f64, pitch: f64) {
        let up = self.up.normalize();
        let offset = self.eye - self.target;
        let offset = rotate(offset, up, yaw);
        // Angle between the offset and up, kept inside (margin, pi - margin).
        let dist = offset.length();
        let polar = (offset.dot(up) / dist).clamp(-1.0, 1.0).acos();
        let new_polar = (polar - pitch).clamp(POLE_MARGIN, std::f64::consts::PI - POLE_MARGIN);
        let right = up.cross(-offset).normalize();
        let offset = rotate(offset, right, polar - new_polar);
        self.eye = self.target + offset;
    }

    /// Slides eye and target in the image plane: `dx`, `dy` in pixels of a `height_px`-high
    /// view (the scene moves with the mouse at the target's distance).
    pub fn pan(&mut self, dx: f64, dy: f64, height_px: f64) {
        let (_, right, up) = self.basis();
        let per_px = 2.0 * self.distance() * (self.fov_y.to_radians() * 0.5).tan() / height_px.max(1.0);
        let shift = (right * -dx + up * dy) * per_px;
        self.eye += shift;
        self.target += shift;
    }

    /// Moves the eye towards the target: the distance is multiplied by `factor` (at least
    /// 10⁻⁶, so the eye never reaches the target; no fixed floor, so a scene 10⁻⁶ units across
    /// can be approached as closely as one 1 unit across).
    pub fn zoom(&mut self, factor: f64) {
        let offset = self.eye - self.target;
        let dist = offset.length();
        let new_dist = dist * factor.max(1e-6);
        self.eye = self.target + offset * (new_dist / dist);
    }

    /// Moves eye and target together: `forward` along the view, `right` along its right,
    /// `up` along the world up (all in scene units).
    pub fn fly(&mut self, forward: f64, right: f64, up: f64) {
        let (f, r, _) = self.basis();
        let shift = f * forward + r * right + self.up.normalize() * up;
        self.eye += shift;
        self.target += shift;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> ViewCamera {
        ViewCamera::from_scene(&Camera {
            eye: V3::new(0.0, 0.0, -5.0),
            look_at: V3::zero(),
            up: V3::new(0.0, 2.0, 0.0),
            fov_y: 40.0,
        })
    }

    #[test]
    fn orbit_keeps_the_distance_and_stops_short_of_the_poles() {
        let mut c = cam();
        c.orbit(0.3, 0.2);
        assert!((c.distance() - 5.0).abs() < 1e-9);
        assert!(c.eye.y > 0.0, "pitching up raises the eye: {:?}", c.eye);
        c.orbit(0.0, 10.0);
        let (f, _, _) = c.basis();
        assert!(f.dot(c.up.normalize()).abs() < 1.0 - 1e-6, "never looks straight down: {f:?}");
        // Yaw to the right: looking along +z, the eye moves towards -x.
        let mut c = cam();
        c.orbit(0.1, 0.0);
        assert!(c.eye.x < 0.0, "{:?}", c.eye);
    }

    #[test]
    fn pan_zoom_and_fly_move_as_named() {
        let mut c = cam();
        c.pan(10.0, 0.0, 100.0);
        assert!(c.target.x < 0.0 && c.eye.x < 0.0, "dragging right moves the view left");
        let mut c = cam();
        c.zoom(0.5);
        assert!((c.distance() - 2.5).abs() < 1e-9 && c.target == V3::zero());
        // Zooming is relative at every scale: from 5 to 5e-9 in three steps.
        for _ in 0..3 {
            c.zoom(1e-3);
        }
        assert!((c.distance() / 2.5e-9 - 1.0).abs() < 1e-9, "{}", c.distance());
        let mut c = cam();
        c.fly(1.0, 2.0, 3.0);
        assert_eq!(c.eye, V3::new(2.0, 3.0, -4.0));
        assert_eq!(c.to_camera().look_at, V3::new(2.0, 3.0, 1.0));
    }
}
