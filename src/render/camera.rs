//! The orbit camera of the viewer and of headless renders: a target point, yaw/pitch/distance, a
//! vertical field of view; view and projection matrices (right-handed, wgpu depth 0..1) and the eye
//! ray through a pixel (tool input).

use glam::{Mat4, Vec3, Vec4};

#[derive(Clone, Debug, PartialEq)]
pub struct OrbitCamera {
    /// The point orbited (simulation coordinates) \[m\].
    pub target: Vec3,
    /// Rotation about +y \[rad\] (0: looking along −z).
    pub yaw: f32,
    /// Elevation \[rad\], positive looks down.
    pub pitch: f32,
    pub distance: f32,
    pub fov_y: f32,
    /// World "up" (+y, or +z in scenarios whose gravity points along −z).
    pub up: Vec3,
}

impl Default for OrbitCamera {
    fn default() -> Self {
        OrbitCamera { target: Vec3::ZERO, yaw: 0.5, pitch: 0.45, distance: 0.3, fov_y: 40f32.to_radians(), up: Vec3::Y }
    }
}

impl OrbitCamera {
    /// A camera looking at the box [min, max] from the front-right-above, the whole box in view.
    /// `flat` (2-D scenarios): straight on, along −z.
    pub fn fit(min: Vec3, max: Vec3, flat: bool, up: Vec3) -> OrbitCamera {
        let centre = (min + max) * 0.5;
        let radius = ((max - min).length() * 0.5).max(1e-4);
        let fov_y = 40f32.to_radians();
        let distance = radius / (fov_y * 0.5).sin() * 1.05;
        if flat {
            OrbitCamera { target: centre, yaw: 0.0, pitch: 0.0, distance, fov_y, up: Vec3::Y }
        } else {
            OrbitCamera { target: centre, yaw: 0.6, pitch: 0.45, distance, fov_y, up }
        }
    }

    /// Two horizontal axes (a, b) completing `up`: yaw 0 puts the eye along +b.
    fn horizontal(&self) -> (Vec3, Vec3) {
        if self.up.z.abs() > 0.9 { (Vec3::X, -Vec3::Y) } else { (Vec3::X, Vec3::Z) }
    }

    /// Direction from the target to the eye.
    fn back(&self) -> Vec3 {
        let (a, b) = self.horizontal();
        let up = self.up.normalize_or(Vec3::Y);
        a * (self.yaw.sin() * self.pitch.cos()) + up * self.pitch.sin() + b * (self.yaw.cos() * self.pitch.cos())
    }

    pub fn eye(&self) -> Vec3 {
        self.target + self.back() * self.distance
    }

    /// Unit vector the camera looks along.
    pub fn forward(&self) -> Vec3 {
        -self.back()
    }

    /// World → view (right-handed, looking along −z of the view frame).
    pub fn view(&self) -> Mat4 {
        let eye = self.eye();
        let f = self.forward();
        let s = f.cross(self.up.normalize_or(Vec3::Y)).normalize_or(Vec3::X);
        let u = s.cross(f);
        Mat4::from_cols(
            Vec4::new(s.x, u.x, -f.x, 0.0),
            Vec4::new(s.y, u.y, -f.y, 0.0),
            Vec4::new(s.z, u.z, -f.z, 0.0),
            Vec4::new(-s.dot(eye), -u.dot(eye), f.dot(eye), 1.0),
        )
    }

    /// View → clip: perspective with wgpu's depth range 0..1 (near → 0).
    pub fn proj(&self, aspect: f32) -> Mat4 {
        let near = (self.distance * 0.01).max(1e-5);
        let far = self.distance * 20.0 + 1.0;
        let f = 1.0 / (self.fov_y * 0.5).tan();
        let r = far / (near - far);
        Mat4::from_cols(
            Vec4::new(f / aspect.max(1e-3), 0.0, 0.0, 0.0),
            Vec4::new(0.0, f, 0.0, 0.0),
            Vec4::new(0.0, 0.0, r, -1.0),
            Vec4::new(0.0, 0.0, r * near, 0.0),
        )
    }

    /// Orbit by mouse motion (radians).
    pub fn orbit(&mut self, d_yaw: f32, d_pitch: f32) {
        self.yaw -= d_yaw;
        self.pitch = (self.pitch + d_pitch).clamp(-1.5, 1.5);
    }

    /// Pan by a fraction of the view height.
    pub fn pan(&mut self, dx: f32, dy: f32) {
        let view = self.view();
        let right = Vec3::new(view.x_axis.x, view.y_axis.x, view.z_axis.x);
        let up = Vec3::new(view.x_axis.y, view.y_axis.y, view.z_axis.y);
        let h = 2.0 * self.distance * (self.fov_y * 0.5).tan();
        self.target += (-right * dx + up * dy) * h;
    }

    /// Zoom by a factor (< 1 moves closer).
    pub fn zoom(&mut self, factor: f32) {
        self.distance = (self.distance * factor).clamp(1e-4, 1e3);
    }

    /// Eye ray (origin, unit direction) through pixel (x, y) of a `width` × `height` viewport.
    pub fn ray(&self, x: f32, y: f32, width: f32, height: f32) -> (Vec3, Vec3) {
        let ndc_x = 2.0 * x / width.max(1.0) - 1.0;
        let ndc_y = 1.0 - 2.0 * y / height.max(1.0);
        let t = (self.fov_y * 0.5).tan();
        let aspect = width / height.max(1.0);
        let view = self.view();
        let right = Vec3::new(view.x_axis.x, view.y_axis.x, view.z_axis.x);
        let up = Vec3::new(view.x_axis.y, view.y_axis.y, view.z_axis.y);
        let dir = (self.forward() + right * ndc_x * t * aspect + up * ndc_y * t).normalize();
        (self.eye(), dir)
    }

    /// Where ray (o, d) meets the plane through `p` with normal `n` (None when parallel or behind).
    pub fn ray_plane(o: Vec3, d: Vec3, p: Vec3, n: Vec3) -> Option<Vec3> {
        let denom = d.dot(n);
        if denom.abs() < 1e-6 {
            return None;
        }
        let s = (p - o).dot(n) / denom;
        (s > 0.0).then_some(o + d * s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_hits_target_and_projects_to_centre() {
        let c = OrbitCamera::fit(Vec3::splat(-0.1), Vec3::splat(0.1), false, Vec3::Z);
        let (o, d) = c.ray(400.0, 300.0, 800.0, 600.0);
        let hit = OrbitCamera::ray_plane(o, d, c.target, c.forward()).expect("hit");
        assert!((hit - c.target).length() < 1e-5);
        let clip = c.proj(800.0 / 600.0) * c.view() * c.target.extend(1.0);
        assert!((clip.x / clip.w).abs() < 1e-5 && (clip.y / clip.w).abs() < 1e-5);
    }

    #[test]
    fn pixel_ray_reprojects_to_its_pixel() {
        let c = OrbitCamera::fit(Vec3::splat(-0.1), Vec3::splat(0.1), false, Vec3::Z);
        let (o, d) = c.ray(100.0, 500.0, 800.0, 600.0);
        let p = o + d * c.distance;
        let clip = c.proj(800.0 / 600.0) * c.view() * p.extend(1.0);
        let (sx, sy) = ((clip.x / clip.w + 1.0) * 400.0, (1.0 - clip.y / clip.w) * 300.0);
        assert!((sx - 100.0).abs() < 0.05 && (sy - 500.0).abs() < 0.05, "{sx} {sy}");
    }
}
