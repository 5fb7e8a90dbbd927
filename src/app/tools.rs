//! Mouse-driven tools: the scalpel and the indenter follow the cursor on a horizontal working plane
//! above the tissue and are lowered or raised with the wheel (Shift + wheel, or Q/E); the projectile
//! is fired along the view ray through the cursor. Each is a boundary object of the scenario tagged
//! with a `tool` (a kinematic body of virtual boundary particles, SPEC §4.1): this module turns input
//! into the `PlaceObject` / `MoveObject` / `SetBoundaryMotion` commands that move it, nothing else.

use crate::render::OrbitCamera;
use crate::scenario::{Motion, Region, ToolKind, V3};
use crate::sim::{Command, ObjectPose};
use glam::Vec3;

/// The viewer's tool state.
#[derive(Clone, Debug)]
pub struct ToolInput {
    pub selected: Option<ToolKind>,
    /// Height of the working plane above the top of the tissue [m] (scalpel, indenter).
    pub height: f32,
    /// The target last sent (simulation coordinates), to avoid flooding the channel.
    last_target: Option<Vec3>,
    /// Whether the selected tool is engaged (left button down).
    pub dragging: bool,
    /// Tool speed as a fraction of the tool's `max_speed` (the live "tool speed" slider), 0.05 … 1.
    pub speed_scale: f64,
}

impl Default for ToolInput {
    fn default() -> Self {
        ToolInput { selected: None, height: 0.0, last_target: None, dragging: false, speed_scale: 1.0 }
    }
}

/// What the tools need to know about the scene (simulation coordinates).
pub struct ToolScene<'a> {
    pub objects: &'a [ObjectPose],
    pub origin: [f64; 3],
    pub up: Vec3,
    /// Top of the tissue along `up` [m] and the domain box.
    pub top: f32,
    pub domain_min: Vec3,
    pub domain_max: Vec3,
    /// Smallest particle spacing [m].
    pub dx: f32,
}

impl ToolScene<'_> {
    /// The object index of tool `kind`, if the scenario has one.
    pub fn object_of(&self, kind: ToolKind) -> Option<(usize, &ObjectPose)> {
        self.objects.iter().enumerate().find(|(_, o)| o.tool.as_ref().is_some_and(|t| t.kind == kind))
    }

    fn to_world(&self, p: Vec3) -> V3 {
        [p.x as f64 + self.origin[0], p.y as f64 + self.origin[1], p.z as f64 + self.origin[2]]
    }

    /// Half extents of a tool's shape.
    fn half_extent(pose: &ObjectPose) -> Vec3 {
        match &pose.shape {
            Region::Box { min, max } => Vec3::new(
                ((max[0] - min[0]) * 0.5) as f32,
                ((max[1] - min[1]) * 0.5) as f32,
                ((max[2] - min[2]) * 0.5) as f32,
            ),
            Region::Sphere { radius, .. } => Vec3::splat(*radius as f32),
        }
    }

    /// Keeps a tool centre inside the domain (boundary particles must stay in the grid).
    fn clamp(&self, c: Vec3, half: Vec3) -> Vec3 {
        let lo = self.domain_min + half;
        let hi = (self.domain_max - half).max(lo);
        c.clamp(lo, hi)
    }
}

impl ToolInput {
    /// The cursor's point on the working plane (simulation coordinates).
    fn plane_point(
        &self,
        scene: &ToolScene,
        camera: &OrbitCamera,
        cursor: (f32, f32),
        size: (f32, f32),
    ) -> Option<Vec3> {
        let (o, d) = camera.ray(cursor.0, cursor.1, size.0, size.1);
        let plane_at = scene.up * (scene.top + self.height);
        // A plane seen edge-on: fall back on the plane through the camera target facing the eye.
        OrbitCamera::ray_plane(o, d, plane_at, scene.up)
            .filter(|_| d.dot(scene.up).abs() > 0.05)
            .or_else(|| OrbitCamera::ray_plane(o, d, camera.target, camera.forward()))
    }

    /// The selected tool's kind, object index, half extents and speed (its `max_speed` times the
    /// speed slider, never above `max_speed`), if the scenario has it.
    fn selected_tool(&self, scene: &ToolScene) -> Option<(ToolKind, usize, Vec3, f64)> {
        let kind = self.selected?;
        let (object, pose) = scene.object_of(kind)?;
        let max = pose.tool.as_ref().map_or(0.1, |t| t.max_speed);
        Some((kind, object, ToolScene::half_extent(pose), max * self.speed_scale.clamp(0.05, 1.0)))
    }

    /// The tool centre under the cursor on the working plane, kept inside the domain.
    fn target(
        &self,
        scene: &ToolScene,
        camera: &OrbitCamera,
        cursor: (f32, f32),
        size: (f32, f32),
        half: Vec3,
    ) -> Option<Vec3> {
        self.plane_point(scene, camera, cursor, size).map(|p| scene.clamp(p, half))
    }

    /// Left button pressed over the 3-D view: engage the selected tool.
    pub fn press(
        &mut self,
        scene: &ToolScene,
        camera: &OrbitCamera,
        cursor: (f32, f32),
        size: (f32, f32),
    ) -> Vec<Command> {
        let Some((kind, object, half, speed)) = self.selected_tool(scene) else { return Vec::new() };
        match kind {
            ToolKind::Projectile => {
                // Load it where the view ray enters the domain and fire along the ray.
                let (o, d) = camera.ray(cursor.0, cursor.1, size.0, size.1);
                let start = entry_point(o, d, scene.domain_min + half, scene.domain_max - half).unwrap_or(o);
                let start = scene.clamp(start, half);
                let v = d * speed as f32;
                vec![
                    Command::PlaceObject { object, position: scene.to_world(start) },
                    Command::SetBoundaryMotion {
                        object,
                        motion: Motion::Translate {
                            velocity: [v.x as f64, v.y as f64, v.z as f64],
                            start: 0.0,
                            stop: None,
                        },
                    },
                ]
            }
            ToolKind::Scalpel | ToolKind::Indenter => {
                // Start above the tissue: the working plane rests one tool size above the top.
                self.height = half.dot(scene.up.abs()) + 2.0 * scene.dx;
                self.dragging = true;
                let Some(p) = self.target(scene, camera, cursor, size, half) else { return Vec::new() };
                self.last_target = Some(p);
                vec![Command::PlaceObject { object, position: scene.to_world(p) }]
            }
        }
    }

    /// Cursor moved (or the height changed) while engaged: move the tool towards the cursor.
    pub fn drag(
        &mut self,
        scene: &ToolScene,
        camera: &OrbitCamera,
        cursor: (f32, f32),
        size: (f32, f32),
    ) -> Vec<Command> {
        let Some((kind, object, half, speed)) = self.selected_tool(scene) else { return Vec::new() };
        if kind == ToolKind::Projectile || !self.dragging {
            return Vec::new();
        }
        let Some(p) = self.target(scene, camera, cursor, size, half) else { return Vec::new() };
        if self.last_target.is_some_and(|q| (q - p).length() < 0.25 * scene.dx) {
            return Vec::new();
        }
        self.last_target = Some(p);
        vec![Command::MoveObject { object, target: scene.to_world(p), speed }]
    }

    /// Lower (negative) or raise the working plane by `steps` particle spacings.
    pub fn adjust_height(&mut self, steps: f32, scene: &ToolScene) {
        self.height += steps * scene.dx;
        let lo = scene.domain_min.dot(scene.up.abs()) - scene.top;
        let hi = scene.domain_max.dot(scene.up.abs()) - scene.top;
        self.height = self.height.clamp(lo.min(hi), hi.max(lo));
    }

    pub fn release(&mut self) {
        self.dragging = false;
    }
}

/// Where the ray (o, d) enters the box [lo, hi] (slab method), if it does.
fn entry_point(o: Vec3, d: Vec3, lo: Vec3, hi: Vec3) -> Option<Vec3> {
    let mut t0 = 0.0f32;
    let mut t1 = f32::INFINITY;
    for a in 0..3 {
        if d[a].abs() < 1e-9 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return None;
            }
            continue;
        }
        let (mut ta, mut tb) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
        if ta > tb {
            std::mem::swap(&mut ta, &mut tb);
        }
        t0 = t0.max(ta);
        t1 = t1.min(tb);
    }
    (t0 <= t1).then_some(o + d * t0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entry_point_of_a_box() {
        let p = entry_point(Vec3::new(-1.0, 0.5, 0.5), Vec3::X, Vec3::ZERO, Vec3::ONE).expect("hit");
        assert!((p - Vec3::new(0.0, 0.5, 0.5)).length() < 1e-6);
        assert!(entry_point(Vec3::new(-1.0, 2.0, 0.5), Vec3::X, Vec3::ZERO, Vec3::ONE).is_none());
        // starting inside: the start itself
        let q = entry_point(Vec3::splat(0.5), Vec3::X, Vec3::ZERO, Vec3::ONE).expect("inside");
        assert!((q - Vec3::splat(0.5)).length() < 1e-6);
    }

    /// The live "tool speed" slider scales the tool's speed, never above its `max_speed` nor below 5 %.
    #[test]
    fn tool_speed_is_a_fraction_of_the_maximum() {
        let pose = ObjectPose {
            name: "scalpel".into(),
            shape: Region::Box { min: [0.0; 3], max: [0.001, 0.01, 0.02] },
            centre: [0.0005, 0.005, 0.01],
            velocity: [0.0; 3],
            tool: Some(crate::scenario::Tool { kind: ToolKind::Scalpel, max_speed: 0.2, blade_cut: false }),
            moulded: false,
            bed: Default::default(),
        };
        let objects = [pose];
        let scene = ToolScene {
            objects: &objects,
            origin: [0.0; 3],
            up: Vec3::Y,
            top: 0.0,
            domain_min: Vec3::splat(-1.0),
            domain_max: Vec3::splat(1.0),
            dx: 0.001,
        };
        let mut input = ToolInput { selected: Some(ToolKind::Scalpel), ..Default::default() };
        let speed = |input: &ToolInput| input.selected_tool(&scene).map(|t| t.3);
        assert_eq!(speed(&input), Some(0.2));
        input.speed_scale = 0.25;
        assert_eq!(speed(&input), Some(0.05));
        input.speed_scale = 3.0;
        assert_eq!(speed(&input), Some(0.2));
        input.speed_scale = 0.0;
        assert!(speed(&input).is_some_and(|v| (v - 0.01).abs() < 1e-12));
    }
}
