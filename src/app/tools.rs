//! Mouse-driven tools: the scalpel and the indenter follow the cursor on a horizontal working plane
//! above the tissue and are lowered or raised with the wheel (Shift + wheel, or Q/E); the projectile
//! is fired along the view ray through the cursor. Each is a boundary object of the scenario tagged
//! with a `tool` (a kinematic body of virtual boundary particles, SPEC §4.1): this module turns input
//! into the `PlaceObject` / `MoveObject` commands that move it, nothing else. A tool stops at the
//! scene's rigid objects (the bed, a plate) as an instrument stops at the table: two kinematic bodies
//! do not interact in the model, and tissue caught between them would be squeezed to nothing.

use crate::render::OrbitCamera;
use crate::scenario::{Region, ToolKind, V3};
use crate::sim::{Command, ObjectPose};
use glam::Vec3;

/// The viewer's tool state.
#[derive(Clone, Debug)]
pub struct ToolInput {
    pub selected: Option<ToolKind>,
    /// Height of the working plane above the top of the tissue \[m\] (scalpel, indenter).
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
    /// Top of the tissue along `up` \[m\] and the domain box.
    pub top: f32,
    pub domain_min: Vec3,
    pub domain_max: Vec3,
    /// Smallest particle spacing \[m\].
    pub dx: f32,
}

impl ToolScene<'_> {
    /// The object index of tool `kind`, if the scenario has one.
    pub fn object_of(&self, kind: ToolKind) -> Option<(usize, &ObjectPose)> {
        self.objects.iter().enumerate().find(|(_, o)| o.tool.as_ref().is_some_and(|t| t.kind == kind))
    }

    /// Scenario coordinates to simulation coordinates (`to_world`'s inverse).
    fn to_sim(&self, v: &V3) -> Vec3 {
        Vec3::new((v[0] - self.origin[0]) as f32, (v[1] - self.origin[1]) as f32, (v[2] - self.origin[2]) as f32)
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

    /// The two axes across `up` (the tools' footprint plane; `up` is a coordinate axis).
    fn across(&self) -> [usize; 2] {
        let a = self.up.abs();
        if a.x >= a.y && a.x >= a.z {
            [1, 2]
        } else if a.y >= a.z {
            [0, 2]
        } else {
            [0, 1]
        }
    }

    /// The highest point along `up` of the rigid objects other than the tools (boxes, spheres, a moulded
    /// bed's particles; simulation coordinates) under the footprint of half extents `half` around `c`,
    /// if any lies under it. A box or sphere wholly above the tool there (a scripted plate overhead) is
    /// no floor.
    fn floor_under(&self, c: Vec3, half: Vec3) -> Option<f32> {
        let tool_top = c.dot(self.up) + half.dot(self.up.abs());
        let sim = |v: &V3| self.to_sim(v);
        let [a, b] = self.across();
        let mut top: Option<f32> = None;
        let mut raise = |h: f32| top = Some(top.map_or(h, |t| t.max(h)));
        for o in self.objects.iter().filter(|o| o.tool.is_none()) {
            if o.moulded {
                let reach = 0.5 * self.dx;
                for p in o.bed.iter().map(sim) {
                    if (p[a] - c[a]).abs() <= half[a] + reach && (p[b] - c[b]).abs() <= half[b] + reach {
                        raise(p.dot(self.up));
                    }
                }
                continue;
            }
            match &o.shape {
                Region::Box { min, max } => {
                    let (lo, hi) = (sim(min), sim(max));
                    let overhead = lo.dot(self.up).min(hi.dot(self.up)) >= tool_top;
                    if !overhead
                        && lo[a] <= c[a] + half[a]
                        && hi[a] >= c[a] - half[a]
                        && lo[b] <= c[b] + half[b]
                        && hi[b] >= c[b] - half[b]
                    {
                        raise(lo.dot(self.up).max(hi.dot(self.up)));
                    }
                }
                Region::Sphere { centre, radius } => {
                    let (m, r) = (sim(centre), *radius as f32);
                    // the footprint's point nearest the sphere's axis along `up`
                    let da = (m[a] - c[a]).abs() - half[a];
                    let db = (m[b] - c[b]).abs() - half[b];
                    let d2 = da.max(0.0).powi(2) + db.max(0.0).powi(2);
                    if d2 < r * r && m.dot(self.up) - r < tool_top {
                        raise(m.dot(self.up) + (r * r - d2).sqrt());
                    }
                }
            }
        }
        top
    }

    /// `c` raised, if need be, so that a tool of half extents `half` there keeps one particle spacing
    /// above the rigid objects under it.
    fn above_floor(&self, c: Vec3, half: Vec3) -> Vec3 {
        let Some(floor) = self.floor_under(c, half) else { return c };
        let lowest = c.dot(self.up) - half.dot(self.up.abs());
        let lift = floor + self.dx - lowest;
        if lift > 0.0 { c + self.up * lift } else { c }
    }

    /// Whether a sphere of radius `r` at `c` comes within one particle spacing of a rigid object other
    /// than the tools.
    fn sphere_blocked(&self, c: Vec3, r: f32) -> bool {
        let sim = |v: &V3| self.to_sim(v);
        let reach = r + self.dx;
        self.objects.iter().filter(|o| o.tool.is_none()).any(|o| {
            if o.moulded {
                return o.bed.iter().any(|p| (sim(p) - c).length_squared() < reach * reach);
            }
            match &o.shape {
                Region::Box { min, max } => (c.clamp(sim(min), sim(max)) - c).length_squared() < reach * reach,
                Region::Sphere { centre, radius } => (sim(centre) - c).length() < reach + *radius as f32,
            }
        })
    }

    /// Where a projectile of radius `r` fired from `start` along the unit vector `d` comes to rest: just
    /// before it would meet a rigid object, else where it would leave the domain (sampled every half
    /// particle spacing); `None` when it is blocked where it starts.
    fn projectile_stop(&self, start: Vec3, d: Vec3, r: f32) -> Option<Vec3> {
        if self.sphere_blocked(start, r) {
            return None;
        }
        let half = Vec3::splat(r);
        let reach =
            exit_distance(start, d, self.domain_min + half, (self.domain_max - half).max(self.domain_min + half));
        let step = (0.5 * self.dx).max(1e-6);
        let mut free = start;
        let mut s = step;
        while s <= reach {
            let c = start + d * s;
            if self.sphere_blocked(c, r) {
                return Some(free);
            }
            free = c;
            s += step;
        }
        Some(start + d * reach)
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
        self.plane_point(scene, camera, cursor, size).map(|p| scene.above_floor(scene.clamp(p, half), half))
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
                // Load it where the view ray enters the domain and fire along the ray; it comes to rest
                // before a rigid object (the bed, a plate) or at the domain's edge.
                let (o, d) = camera.ray(cursor.0, cursor.1, size.0, size.1);
                let start = entry_point(o, d, scene.domain_min + half, scene.domain_max - half).unwrap_or(o);
                let start = scene.clamp(start, half);
                let Some(stop) = scene.projectile_stop(start, d.normalize_or_zero(), half.x) else {
                    log::info!("projectile: the view ray enters the scene through a rigid object; not fired");
                    return Vec::new();
                };
                vec![
                    Command::PlaceObject { object, position: scene.to_world(start) },
                    Command::MoveObject { object, target: scene.to_world(stop), speed },
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

/// The parameters [t0, t1] (t0 ≥ 0) over which the ray (o, d) lies in the box [lo, hi] (slab method),
/// if it meets the box.
fn slab(o: Vec3, d: Vec3, lo: Vec3, hi: Vec3) -> Option<(f32, f32)> {
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
    (t0 <= t1).then_some((t0, t1))
}

/// How far the ray (o, d) from a point o inside the box [lo, hi] runs before it leaves the box
/// (|d| = 1); 0 when o is outside or the ray never leaves.
fn exit_distance(o: Vec3, d: Vec3, lo: Vec3, hi: Vec3) -> f32 {
    match slab(o, d, lo - Vec3::splat(1e-6), hi + Vec3::splat(1e-6)) {
        Some((t0, t1)) if t0 == 0.0 && t1.is_finite() => t1,
        _ => 0.0,
    }
}

/// Where the ray (o, d) enters the box [lo, hi], if it does (o itself when it starts inside).
fn entry_point(o: Vec3, d: Vec3, lo: Vec3, hi: Vec3) -> Option<Vec3> {
    slab(o, d, lo, hi).map(|(t0, _)| o + d * t0)
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

    fn pose(name: &str, shape: Region, tool: Option<ToolKind>, bed: Vec<V3>) -> ObjectPose {
        let centre = match &shape {
            Region::Box { min, max } => [0.5 * (min[0] + max[0]), 0.5 * (min[1] + max[1]), 0.5 * (min[2] + max[2])],
            Region::Sphere { centre, .. } => *centre,
        };
        ObjectPose {
            name: name.into(),
            shape,
            centre,
            velocity: [0.0; 3],
            tool: tool.map(|kind| crate::scenario::Tool { kind, max_speed: 1.0, blade_cut: false }),
            moulded: !bed.is_empty(),
            bed: bed.into(),
        }
    }

    /// A plate (top at y = 0 over |x|, |z| ≤ 0.05), a moulded bed (one column of particles at
    /// x ≈ 0.08 up to y = 0.01) and an indenter of radius 5 mm; Δx = 1 mm, origin at (1, 2, 3).
    fn table_scene(objects: &[ObjectPose]) -> ToolScene<'_> {
        ToolScene {
            objects,
            origin: [1.0, 2.0, 3.0],
            up: Vec3::Y,
            top: 0.02,
            domain_min: Vec3::new(-0.1, -0.02, -0.1),
            domain_max: Vec3::new(0.1, 0.1, 0.1),
            dx: 0.001,
        }
    }

    fn table_objects() -> Vec<ObjectPose> {
        let o = [1.0, 2.0, 3.0];
        let w = |x: f64, y: f64, z: f64| [x + o[0], y + o[1], z + o[2]];
        let bed: Vec<V3> = (0..=10).map(|k| w(0.08, 0.001 * k as f64, 0.0)).collect();
        vec![
            pose("plate", Region::Box { min: w(-0.05, -0.01, -0.05), max: w(0.05, 0.0, 0.05) }, None, vec![]),
            pose("bed", Region::Box { min: w(0.07, 0.0, -0.01), max: w(0.09, 0.01, 0.01) }, None, bed),
            pose(
                "indenter",
                Region::Sphere { centre: w(0.0, 0.05, 0.0), radius: 0.005 },
                Some(ToolKind::Indenter),
                vec![],
            ),
        ]
    }

    /// A tool lowered onto the plate or the bed stops one particle spacing above it (its own particles
    /// and the object's are both kinematic: nothing else would stop it); elsewhere, and above them, the
    /// working plane alone decides.
    #[test]
    fn a_tool_stops_one_spacing_above_a_rigid_object() {
        let objects = table_objects();
        let scene = table_scene(&objects);
        let half = Vec3::splat(0.005);
        // pressed into the plate: its lowest point one Δx above the plate's top (y = 0)
        let c = scene.above_floor(Vec3::new(0.01, -0.004, 0.02), half);
        assert!((c - Vec3::new(0.01, 0.006, 0.02)).length() < 1e-6, "{c}");
        // above the plate already: unchanged
        let hi = Vec3::new(0.01, 0.03, 0.02);
        assert_eq!(scene.above_floor(hi, half), hi);
        // over the bed's column (its top particle at y = 0.01): lowest point at 0.011
        let c = scene.above_floor(Vec3::new(0.084, 0.0, 0.0), half);
        assert!((c.y - 0.016).abs() < 1e-6, "{c}");
        // beside both (x = 0.065: past the plate's edge, the bed column more than r + Δx/2 away): free
        let free = Vec3::new(0.0655 - 0.005 - 0.001, -0.015, 0.0);
        assert_eq!(scene.above_floor(free, half), free);
        // a plate overhead is no floor
        let mut with_lid = table_objects();
        with_lid.push(pose("lid", Region::Box { min: [0.95, 2.06, 2.95], max: [1.05, 2.07, 3.05] }, None, vec![]));
        let lidded = table_scene(&with_lid);
        assert_eq!(lidded.above_floor(hi, half), hi);
        // the tool itself is no obstacle
        assert!(objects[2].tool.is_some() && scene.floor_under(Vec3::new(0.0, 0.05, 0.0), half) == Some(0.0));
    }

    /// The projectile fired at the plate comes to rest just above it; fired over it, at the domain's
    /// edge; loaded inside a rigid object, it is not fired.
    #[test]
    fn a_projectile_comes_to_rest_before_a_rigid_object() {
        let objects = table_objects();
        let scene = table_scene(&objects);
        let r = 0.005;
        let down = Vec3::new(0.3, -1.0, 0.1).normalize();
        let stop = scene.projectile_stop(Vec3::new(-0.02, 0.09, 0.0), down, r).expect("fired");
        // centre within r + Δx of the plate's top, and no closer
        assert!(stop.y >= r + scene.dx - 1e-6 && stop.y <= r + 1.6 * scene.dx, "stops at {stop}");
        let along = Vec3::X;
        let stop = scene.projectile_stop(Vec3::new(-0.095, 0.05, 0.0), along, r).expect("fired");
        assert!((stop - Vec3::new(0.095, 0.05, 0.0)).length() < 1e-5, "leaves the domain at {stop}");
        assert!(scene.projectile_stop(Vec3::new(0.0, -0.005, 0.0), down, r).is_none());
        assert!((exit_distance(Vec3::ZERO, Vec3::X, Vec3::splat(-1.0), Vec3::splat(2.0)) - 2.0).abs() < 1e-6);
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
