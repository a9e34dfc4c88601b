//! The viewer's camera: orbit around the target or fly from the eye, with the mouse and
//! WASD. The [`hyrt::Camera`] is the state; a move turns it into angles about its up
//! axis, changes them, and writes it back, so an unmoved camera stays bit for bit the one
//! it started as (the viewer's screenshot then equals `hyrt render` of that camera).

use hyrt::glam::Vec3;
use hyrt::Camera;

/// How mouse drags and WASD move the camera.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Drag turns the eye around the target; the wheel and W/S change the distance.
    Orbit,
    /// Drag turns the view about the eye; WASD moves the eye (Q/E down and up).
    Fly,
}

impl Mode {
    pub fn name(self) -> &'static str {
        match self {
            Mode::Orbit => "orbit",
            Mode::Fly => "fly",
        }
    }
}

/// The camera and how it moves.
#[derive(Clone, Debug)]
pub struct Controller {
    pub camera: Camera,
    pub mode: Mode,
    /// World units per second in fly mode (from the scene's size).
    pub speed: f32,
}

/// An orthonormal frame about `up`: (up, a, b) with a, b spanning the horizon.
fn basis(up: Vec3) -> (Vec3, Vec3, Vec3) {
    let up = up.normalize();
    let a = up.any_orthonormal_vector();
    (up, a, up.cross(a))
}

/// A direction as (yaw, pitch) about `up`.
fn angles(d: Vec3, up: Vec3) -> (f32, f32) {
    let (u, a, b) = basis(up);
    let d = d.normalize();
    (d.dot(b).atan2(d.dot(a)), d.dot(u).clamp(-1.0, 1.0).asin())
}

/// The unit direction of (yaw, pitch) about `up`.
fn direction(yaw: f32, pitch: f32, up: Vec3) -> Vec3 {
    let (u, a, b) = basis(up);
    (a * yaw.cos() + b * yaw.sin()) * pitch.cos() + u * pitch.sin()
}

/// Pitch stays this far from straight up or down, where yaw is undefined.
const MAX_PITCH: f32 = 1.55;

impl Controller {
    pub fn new(camera: Camera, scene_size: f32) -> Controller {
        Controller { camera, mode: Mode::Orbit, speed: (scene_size * 0.2).max(0.1) }
    }

    /// Turn by a mouse drag of (dx, dy) radians.
    pub fn rotate(&mut self, dx: f32, dy: f32) {
        let c = &mut self.camera;
        match self.mode {
            Mode::Orbit => {
                let offset = c.eye - c.target;
                let (yaw, pitch) = angles(offset, c.up);
                let pitch = (pitch + dy).clamp(-MAX_PITCH, MAX_PITCH);
                c.eye = c.target + direction(yaw - dx, pitch, c.up) * offset.length();
            }
            Mode::Fly => {
                let view = c.target - c.eye;
                let (yaw, pitch) = angles(view, c.up);
                let pitch = (pitch - dy).clamp(-MAX_PITCH, MAX_PITCH);
                c.target = c.eye + direction(yaw - dx, pitch, c.up) * view.length();
            }
        }
    }

    /// Move toward the target by `factor` of the distance (orbit; negative: away).
    pub fn zoom(&mut self, factor: f32) {
        let c = &mut self.camera;
        let offset = c.eye - c.target;
        c.eye = c.target + offset * (1.0 - factor).clamp(0.05, 20.0);
    }

    /// Move by `forward`, `right`, `up` (each in [-1, 1]) over `dt` seconds: the eye and
    /// target together in fly mode; in orbit mode forward zooms and the rest turns.
    pub fn travel(&mut self, forward: f32, right: f32, up: f32, dt: f32) {
        if forward == 0.0 && right == 0.0 && up == 0.0 {
            return;
        }
        match self.mode {
            Mode::Orbit => {
                self.zoom(forward * dt);
                self.rotate(-right * dt, up * dt);
            }
            Mode::Fly => {
                let c = &mut self.camera;
                let f = (c.target - c.eye).normalize();
                let r = f.cross(c.up).normalize();
                let step = (f * forward + r * right + c.up.normalize() * up) * self.speed * dt;
                c.eye += step;
                c.target += step;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_orbit_comes_back_and_keeps_the_distance() {
        let start = Camera::look_at(Vec3::new(0.0, 2.0, 8.0), Vec3::ZERO, Vec3::Y);
        let mut c = Controller::new(start, 10.0);
        for _ in 0..8 {
            c.rotate(std::f32::consts::FRAC_PI_4, 0.0);
        }
        assert!((c.camera.eye - start.eye).length() < 1e-3, "{:?}", c.camera.eye);
        c.mode = Mode::Fly;
        c.travel(1.0, 0.0, 0.0, 1.0);
        assert!((c.camera.eye - c.camera.target).length() > 1.0);
    }
}
