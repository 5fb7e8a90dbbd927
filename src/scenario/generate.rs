//! Particle generators: lattices in boxes and balls, perfused blocks, boundary objects, and the
//! particle masses of SPEC §1.2 / D-2 (m = n₀ρ₀/S_W) and §4.1 (boundary equivalent masses).

use super::{Generator, InitialVelocity, Motion, Phase, PressureMode, Region, Scenario, Tool, V3};
use crate::sim::kernels::{Dim, lattice_poly6_sum};

/// Flags of a solid particle (bit set), mirrored in `shaders/common.wgsl` (`SOLID_*`).
pub struct SolidFlags;
impl SolidFlags {
    /// Position prescribed (clamp, ligament, porous skeleton held still): SPEC §4.2.
    pub const KINEMATIC: u32 = 1;
    /// Membrane (Glisson's capsule) particle: SPEC §4.5.
    pub const MEMBRANE: u32 = 2;
    /// Tied to its initial position by a damped spring (`Scenario::ligaments`); never set together
    /// with `KINEMATIC`.
    pub const TETHERED: u32 = 4;
}

/// Particles of one phase as generated (f64, absolute coordinates).
#[derive(Clone, Debug, Default)]
pub struct PhaseParticles {
    pub pos: Vec<V3>,
    pub vel: Vec<V3>,
    pub mass: Vec<f64>,
}

/// One rigid boundary object.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct BoundaryObject {
    pub name: String,
    pub shape: Region,
    pub motion: Motion,
    pub pressure: PressureMode,
    /// Coulomb μ of solid contact (`Boundary::friction`; None: SPEC §4.1 contact).
    pub friction: Option<f64>,
    pub spacing: f64,
    /// Set when the user drives this object (viewer tools).
    pub tool: Option<Tool>,
    /// A bed moulded to the tissue (`Boundary::mould`): its particles are not its shape's lattice, so
    /// it gets no contact projection and is not drawn as its shape.
    pub moulded: bool,
    /// A moulded bed's particles at rest (absolute coordinates): what the renderer draws of it. Shared,
    /// so that the poses published with every frame do not copy it.
    #[serde(default)]
    pub bed: std::sync::Arc<[V3]>,
}

/// Everything a back-end needs to build its initial state, plus the derived per-phase sizes.
#[derive(Clone, Debug, Default)]
pub struct GeneratedParticles {
    pub liquid: PhaseParticles,
    pub solid: PhaseParticles,
    pub solid_flags: Vec<u32>,
    /// Equivalent mass a solid particle shows the liquid when it is a membrane (boundary) particle.
    pub solid_liquid_boundary_mass: Vec<f64>,
    /// Outward unit normal of a membrane particle in the generated configuration (its parent's n̂ of
    /// SPEC §4.5's detection; zero for the tissue): the side of its ghost sites and seal.
    pub solid_normal: Vec<V3>,
    pub boundary_pos: Vec<V3>,
    pub boundary_object: Vec<u32>,
    pub boundary_mass_liquid: Vec<f64>,
    pub boundary_mass_solid: Vec<f64>,
    /// Per boundary particle: it stands in a cavity in the tissue's place (in the lattice cell of a
    /// solid particle the cavity removed — a needle's walls inside the specimen), so it continues the
    /// solid in the liquid's nˢ as it continues the liquid in ρˡ (§4.1; README: deviations from SPEC).
    pub boundary_in_tissue: Vec<bool>,
    pub objects: Vec<BoundaryObject>,
    /// Δx and h of each phase \[m\] (0 where the phase is absent).
    pub dx_liquid: f64,
    pub dx_solid: f64,
    pub h_liquid: f64,
    pub h_solid: f64,
    /// Particle mass of each phase \[kg\] (m = n₀ρ₀/S_W), and its n₀.
    pub mass_liquid: f64,
    pub mass_solid: f64,
    pub fraction_liquid: f64,
    pub fraction_solid: f64,
    /// Inlets (scenario `emitters`), in scenario order.
    pub emitters: Vec<EmitterSlots>,
    /// Sink regions (scenario `sinks`).
    pub sinks: Vec<Region>,
    /// Most liquid particles the back-ends make room for (≥ the initial liquid).
    pub liquid_capacity: usize,
}

/// One inlet as generated: its slots (lattice sites inside the region, absolute coordinates), the mass
/// and velocity of the particles it adds, and its flow.
#[derive(Clone, Debug)]
pub struct EmitterSlots {
    pub name: String,
    pub region: Region,
    pub slots: Vec<V3>,
    pub mass: f64,
    /// Unit inflow direction (z = 0 in 2-D).
    pub direction: V3,
    /// Depth L of the slot lattice along `direction` (extent of the slots' projections + Δx_l) \[m\].
    pub depth: f64,
    pub flow: super::Flow,
}

/// Extra liquid capacity for emitters when the scenario gives no `liquid_capacity`.
pub const DEFAULT_EMITTER_ROOM: usize = 20_000;

/// Number of lattice points `lattice_points` would produce (used by validation).
pub fn lattice_count(region: &Region, dx: f64, d: usize) -> usize {
    match region {
        Region::Box { min, max } => (0..d).map(|a| box_cells(max[a] - min[a], dx)).product(),
        Region::Sphere { .. } => lattice_points(region, dx, d).len(),
    }
}

fn box_cells(extent: f64, dx: f64) -> usize {
    if !(extent > 0.0 && dx > 0.0) {
        return 0;
    }
    let n = (extent / dx + 1e-6).floor();
    if n > 1e8 { usize::MAX / 8 } else { n as usize }
}

/// Cell-centred lattice points of spacing `dx` inside `region` (z = 0 in 2-D), in a fixed order
/// (x fastest, then y, then z).
pub fn lattice_points(region: &Region, dx: f64, d: usize) -> Vec<V3> {
    let mut out = Vec::new();
    match region {
        Region::Box { min, max } => {
            let mut n = [1usize; 3];
            let mut start = [0.0f64; 3];
            for a in 0..d {
                let ext = max[a] - min[a];
                n[a] = box_cells(ext, dx);
                start[a] = min[a] + 0.5 * (ext - n[a] as f64 * dx) + 0.5 * dx;
            }
            if n.iter().product::<usize>() > 50_000_000 {
                return out;
            }
            for k in 0..n[2] {
                for j in 0..n[1] {
                    for i in 0..n[0] {
                        let z = if d == 3 { start[2] + k as f64 * dx } else { 0.0 };
                        out.push([start[0] + i as f64 * dx, start[1] + j as f64 * dx, z]);
                    }
                }
            }
        }
        Region::Sphere { centre, radius } => {
            let n = (radius / dx).floor() as i64;
            if n > 2000 {
                return out;
            }
            let nz = if d == 3 { n } else { 0 };
            for k in -nz..=nz {
                for j in -n..=n {
                    for i in -n..=n {
                        let p = [i as f64 * dx, j as f64 * dx, k as f64 * dx];
                        if p[0] * p[0] + p[1] * p[1] + p[2] * p[2] <= radius * radius * (1.0 + 1e-9) {
                            let z = if d == 3 { centre[2] + p[2] } else { 0.0 };
                            out.push([centre[0] + p[0], centre[1] + p[1], z]);
                        }
                    }
                }
            }
        }
    }
    out
}

/// Cell-centred points of a sheet generator (see `Generator::Sheet`), x fastest.
pub fn sheet_points(centre: V3, size: (f64, f64), dx: f64, d: usize) -> Vec<V3> {
    let (min, max) = if d == 3 {
        (
            [centre[0] - 0.5 * size.0, centre[1] - 0.5 * size.1, 0.0],
            [centre[0] + 0.5 * size.0, centre[1] + 0.5 * size.1, 0.0],
        )
    } else {
        ([centre[0] - 0.5 * size.0, 0.0, 0.0], [centre[0] + 0.5 * size.0, 0.0, 0.0])
    };
    let plane = d - 1;
    let mut out = lattice_points(&Region::Box { min, max }, dx, plane);
    for p in &mut out {
        if d == 3 {
            p[2] = centre[2];
        } else {
            p[1] = centre[1];
        }
    }
    out
}

/// First clamped–free bending mode shape φ(x) with βL = 1.8751041 (SPEC §7.2), φ(L) = 2.
pub fn cantilever_mode(x: f64, length: f64) -> f64 {
    let bl = 1.875_104_1_f64;
    let sigma = (bl.cosh() + bl.cos()) / (bl.sinh() + bl.sin());
    let b = bl / length;
    let bx = b * x;
    bx.cosh() - bx.cos() - sigma * (bx.sinh() - bx.sin())
}

fn initial_velocity(v: &Option<InitialVelocity>, p: V3) -> V3 {
    match v {
        None => [0.0; 3],
        Some(InitialVelocity::Uniform(u)) => *u,
        Some(InitialVelocity::CantileverMode { root, length, amplitude, direction }) => {
            let x = (p[0] - root).clamp(0.0, *length);
            let s = amplitude * cantilever_mode(x, *length) / cantilever_mode(*length, *length);
            [s * direction[0], s * direction[1], s * direction[2]]
        }
    }
}

/// Generates every particle of a validated scenario.
pub fn generate(s: &Scenario) -> GeneratedParticles {
    let d = s.dimensions as usize;
    let dim = if d == 2 { Dim::Two } else { Dim::Three };
    let n = &s.numerics;
    let mut g = GeneratedParticles {
        dx_liquid: n.dx_liquid.unwrap_or(0.0),
        dx_solid: n.dx_solid.unwrap_or(0.0),
        ..Default::default()
    };
    g.h_liquid = n.h_liquid.unwrap_or(n.h_over_dx * g.dx_liquid);
    g.h_solid = n.h_solid.unwrap_or(n.h_over_dx * g.dx_solid);
    // The scenario's liquid n₀ (boundary and membrane equivalent masses, emitters) is that of its first
    // liquid generator, the perfusing blood; a later one may differ (a syringe primed with pure blood,
    // SPEC §7.8) and gives its own particles the mass of its own fraction.
    let mut liquid_seen = false;
    for spec in &s.particles {
        match spec {
            Generator::Box { phase, fraction, .. } | Generator::Sphere { phase, fraction, .. } => match phase {
                Phase::Liquid if !liquid_seen => {
                    g.fraction_liquid = *fraction;
                    liquid_seen = true;
                }
                Phase::Liquid => {}
                Phase::Solid => g.fraction_solid = *fraction,
            },
            Generator::PerfusedBlock { solid_fraction, liquid_fraction, .. }
            | Generator::PerfusedMesh { solid_fraction, liquid_fraction, .. } => {
                g.fraction_solid = *solid_fraction;
                if !liquid_seen {
                    g.fraction_liquid = *liquid_fraction;
                    liquid_seen = true;
                }
            }
            Generator::Sheet { fraction, .. } => g.fraction_solid = *fraction,
        }
    }
    // Without liquid generators the emitted liquid sets n₀ (boundary masses depend on it).
    if g.fraction_liquid == 0.0
        && let Some(e) = s.emitters.first()
    {
        g.fraction_liquid = e.fraction.unwrap_or(1.0);
    }
    // m = n₀ρ₀/S_W of a liquid lattice of fraction n₀ (D-2).
    let (dx_l, h_l) = (g.dx_liquid, g.h_liquid);
    let liquid_mass = |fraction: f64| match &s.liquid {
        Some(l) if dx_l > 0.0 => fraction * l.density / lattice_poly6_sum(dx_l, 2.0 * h_l, dim),
        _ => 0.0,
    };
    g.mass_liquid = liquid_mass(g.fraction_liquid);
    if let Some(m) = &s.solid
        && g.dx_solid > 0.0
    {
        g.mass_solid = g.fraction_solid * m.density / lattice_poly6_sum(g.dx_solid, 2.0 * g.h_solid, dim);
    }

    let push =
        |phase: Phase, region: &Region, fraction: f64, vel: &Option<InitialVelocity>, g: &mut GeneratedParticles| {
            let (dx, mass) = match phase {
                Phase::Liquid => (g.dx_liquid, liquid_mass(fraction)),
                Phase::Solid => (g.dx_solid, g.mass_solid),
            };
            let set = match phase {
                Phase::Liquid => &mut g.liquid,
                Phase::Solid => &mut g.solid,
            };
            for p in lattice_points(region, dx, d) {
                set.vel.push(initial_velocity(vel, p));
                set.pos.push(p);
                set.mass.push(mass);
            }
        };
    // Liquid generated inside meshes: kept beneath the capsule below.
    let mut mesh_liquid: Vec<std::ops::Range<usize>> = Vec::new();
    // Per liquid particle: generated by a perfused generator (the tissue's blood, what a cavity
    // empties); kept in step with `g.liquid` through the capsule's filtering below.
    let mut perfusing: Vec<bool> = Vec::new();
    for spec in &s.particles {
        let perfused = matches!(spec, Generator::PerfusedBlock { .. } | Generator::PerfusedMesh { .. });
        match spec {
            Generator::Box { phase, min, max, fraction, velocity } => {
                push(*phase, &Region::Box { min: *min, max: *max }, *fraction, velocity, &mut g)
            }
            Generator::Sphere { phase, centre, radius, fraction, velocity } => {
                push(*phase, &Region::Sphere { centre: *centre, radius: *radius }, *fraction, velocity, &mut g)
            }
            Generator::PerfusedBlock { min, max, solid_fraction, liquid_fraction } => {
                let r = Region::Box { min: *min, max: *max };
                push(Phase::Solid, &r, *solid_fraction, &None, &mut g);
                push(Phase::Liquid, &r, *liquid_fraction, &None, &mut g);
            }
            Generator::Sheet { centre, size, fraction } => {
                // A sheet's particles stand for the fabric's thickness: the mass follows the in-plane
                // lattice sum with the cross-phase kernel R_× (SPEC §7.12).
                let r_x = 2.0 * g.h_liquid.max(g.h_solid);
                let mass = match &s.solid {
                    Some(m) if g.dx_solid > 0.0 => {
                        fraction * m.density / crate::sim::kernels::sheet_poly6_sum(g.dx_solid, r_x, dim)
                    }
                    _ => 0.0,
                };
                for p in sheet_points(*centre, *size, g.dx_solid, d) {
                    g.solid.vel.push([0.0; 3]);
                    g.solid.pos.push(p);
                    g.solid.mass.push(mass);
                }
            }
            Generator::PerfusedMesh { file, placement, liquid_fraction, .. } => {
                // Validation loaded this mesh already; an error here leaves the generator empty.
                if let Ok(mesh) = super::mesh::load_mesh(&s.resolve(file)) {
                    let mesh = mesh.transformed(placement);
                    let (ms, ml) = (g.mass_solid, liquid_mass(*liquid_fraction));
                    for (phase, dx, mass) in [(Phase::Solid, g.dx_solid, ms), (Phase::Liquid, g.dx_liquid, ml)] {
                        let pts = super::mesh::sample_interior(&mesh, dx, mesh_lattice_offset(phase, dx));
                        if phase == Phase::Liquid {
                            mesh_liquid.push(g.liquid.pos.len()..g.liquid.pos.len() + pts.len());
                        }
                        let set = if phase == Phase::Solid { &mut g.solid } else { &mut g.liquid };
                        for p in pts {
                            set.vel.push([0.0; 3]);
                            set.pos.push(p);
                            set.mass.push(mass);
                        }
                    }
                }
            }
        }
        perfusing.resize(g.liquid.pos.len(), perfused);
    }
    let (membrane, parent, normal) = match &s.membrane {
        Some(m) if !g.solid.pos.is_empty() => {
            let (flags, capsule, parent) = add_membrane(&mut g, m, d);
            keep_liquid_beneath_capsule(&mut g, &mesh_liquid, &capsule, &mut perfusing);
            // a child's outward normal is its parent's (capsule holds the parents' in index order)
            let mut by_parent: std::collections::HashMap<usize, V3> = std::collections::HashMap::new();
            let parents = (0..parent.len()).filter(|&i| flags[i] && parent[i] == i);
            for (i, (_, n_hat)) in parents.zip(&capsule) {
                by_parent.insert(i, *n_hat);
            }
            let normal = (0..parent.len())
                .map(|i| if flags[i] { by_parent.get(&parent[i]).copied().unwrap_or([0.0; 3]) } else { [0.0; 3] })
                .collect();
            (flags, parent, normal)
        }
        _ => (vec![false; g.solid.pos.len()], (0..g.solid.pos.len()).collect(), vec![[0.0; 3]; g.solid.pos.len()]),
    };
    g.solid_normal = normal;
    // A capsule child is fixed (or tethered) with its parent (the two are one lattice site, SPEC
    // §4.1/§4.5): a child left free beside a kinematic parent, on the rim of a fixed region, was
    // squeezed out of the ligament region during the liver's relaxation and broke all 17 bonds that
    // broke there.
    let tether_regions = s.ligaments.as_ref().map(|l| l.regions.as_slice()).unwrap_or(&[]);
    g.solid_flags = (0..g.solid.pos.len())
        .map(|i| {
            let site = g.solid.pos[parent[i]];
            let inside = |regions: &[Region]| regions.iter().any(|r| r.contains(site, s.dimensions));
            let hold = if inside(&s.fixed_regions) {
                SolidFlags::KINEMATIC
            } else if inside(tether_regions) {
                SolidFlags::TETHERED
            } else {
                0
            };
            hold | if membrane[i] { SolidFlags::MEMBRANE } else { 0 }
        })
        .collect();
    // A membrane particle shows the liquid the equivalent mass of its share of a solid lattice site (§4.1).
    let n_share = s.membrane.as_ref().map(|m| membrane_children(m, d) as f64 + 1.0).unwrap_or(1.0);
    let m_bl =
        if g.dx_liquid > 0.0 { g.mass_liquid * (g.dx_solid / g.dx_liquid).powi(d as i32) / n_share } else { 0.0 };
    g.solid_liquid_boundary_mass = membrane.iter().map(|&mem| if mem { m_bl } else { 0.0 }).collect();
    let removed_solid = empty_cavities(&mut g, s, &perfusing);
    let in_tissue = TissueSites::new(&removed_solid, g.dx_solid, d);

    let default_spacing = if g.dx_solid > 0.0 { g.dx_solid } else { g.dx_liquid };
    for (k, b) in s.boundaries.iter().enumerate() {
        let sp = b.spacing.unwrap_or(default_spacing);
        let ml = if g.dx_liquid > 0.0 { g.mass_liquid * (sp / g.dx_liquid).powi(d as i32) } else { 0.0 };
        let ms = if g.dx_solid > 0.0 { g.mass_solid * (sp / g.dx_solid).powi(d as i32) } else { 0.0 };
        let mut points = lattice_points(&b.shape, sp, d);
        if let Some(m) = &b.mould {
            let fixed: Vec<bool> = g.solid_flags.iter().map(|f| f & SolidFlags::KINEMATIC != 0).collect();
            points = moulded_bed(points, &g.solid.pos, &fixed, s.gravity, m, sp);
        }
        let bed = if b.mould.is_some() { points.as_slice().into() } else { std::sync::Arc::default() };
        for p in points {
            g.boundary_pos.push(p);
            g.boundary_object.push(k as u32);
            g.boundary_mass_liquid.push(ml);
            g.boundary_mass_solid.push(ms);
            g.boundary_in_tissue.push(in_tissue.covers(p));
        }
        g.objects.push(BoundaryObject {
            name: b.name.clone(),
            shape: b.shape.clone(),
            motion: b.motion.clone(),
            pressure: b.pressure.clone(),
            friction: b.friction,
            spacing: sp,
            tool: b.tool.clone(),
            moulded: b.mould.is_some(),
            bed,
        });
    }
    for e in &s.emitters {
        let mass = match (&s.liquid, e.fraction) {
            (Some(l), Some(fr)) if g.dx_liquid > 0.0 => {
                fr * l.density / lattice_poly6_sum(g.dx_liquid, 2.0 * g.h_liquid, dim)
            }
            _ => g.mass_liquid,
        };
        let mut dir = if d == 2 { [e.direction[0], e.direction[1], 0.0] } else { e.direction };
        let len = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
        if len > 0.0 {
            dir = [dir[0] / len, dir[1] / len, dir[2] / len];
        }
        let slots = lattice_points(&e.region, g.dx_liquid, d);
        let proj = |p: &V3| p[0] * dir[0] + p[1] * dir[1] + p[2] * dir[2];
        let lo = slots.iter().map(proj).fold(f64::INFINITY, f64::min);
        let hi = slots.iter().map(proj).fold(f64::NEG_INFINITY, f64::max);
        let depth = if slots.is_empty() { 0.0 } else { hi - lo + g.dx_liquid };
        g.emitters.push(EmitterSlots {
            name: e.name.clone(),
            region: e.region.clone(),
            slots,
            mass,
            direction: dir,
            depth,
            flow: e.flow.clone(),
        });
    }
    g.sinks = s.sinks.iter().map(|k| k.region.clone()).collect();
    let room = if s.emitters.is_empty() { 0 } else { DEFAULT_EMITTER_ROOM };
    g.liquid_capacity = s.liquid_capacity.map_or(g.liquid.pos.len() + room, |c| c as usize);
    g
}

/// The lattice points of a bed moulded to the tissue (`Boundary::mould`): those at least `clearance`
/// from every solid particle that have a solid particle above them in their column — along −ĝ, within
/// `clearance + depth`, less than ¾ of a bed spacing `sp` off the vertical (every point under a lattice
/// of spacing ≤ `sp` has a column that close: ≤ √2/2 of it) — and none level with or below them there
/// (which a point in a gap of the tissue's own lattice has), so the bed fills the space under the
/// tissue's lower face to `depth` and nothing beside, inside or above it. Columns with a `fixed`
/// (kinematic) particle anywhere above are left out: free tissue between a ligament's fixed region and
/// the bed was squeezed there (J ≈ 0.82 on `liver.ron`'s thin left lobe) and jittered at ~0.1 m/s.
pub fn moulded_bed(points: Vec<V3>, solid: &[V3], fixed: &[bool], gravity: V3, m: &super::Mould, sp: f64) -> Vec<V3> {
    let g = (gravity[0] * gravity[0] + gravity[1] * gravity[1] + gravity[2] * gravity[2]).sqrt();
    if g.is_nan() || g <= 0.0 {
        return Vec::new();
    }
    let up = [-gravity[0] / g, -gravity[1] / g, -gravity[2] / g];
    let reach = (m.clearance + m.depth).max(sp);
    let cell = |p: &V3| -> [i64; 3] { [0, 1, 2].map(|a| (p[a] / reach).floor() as i64) };
    let mut grid: std::collections::HashMap<[i64; 3], Vec<usize>> = std::collections::HashMap::new();
    for (i, q) in solid.iter().enumerate() {
        grid.entry(cell(q)).or_default().push(i);
    }
    let pins: Vec<V3> = solid.iter().zip(fixed).filter(|(_, f)| **f).map(|(q, _)| *q).collect();
    // q seen from p: height above it along −ĝ, squared distance off its vertical, squared distance
    let offset = |q: &V3, p: &V3| {
        let d = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
        let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        let along = d[0] * up[0] + d[1] * up[1] + d[2] * up[2];
        (along, (r2 - along * along).max(0.0), r2)
    };
    let in_column = |lateral2: f64| lateral2 < 0.5625 * sp * sp;
    let keep = |p: &V3| {
        let c = cell(p);
        let (mut under, mut clear, mut inside) = (false, true, false);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(list) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else { continue };
                    for &i in list {
                        let (along, lateral2, r2) = offset(&solid[i], p);
                        if r2 < m.clearance * m.clearance {
                            clear = false;
                        }
                        let column = in_column(lateral2);
                        under |= column && along > 0.0 && along <= m.clearance + m.depth;
                        // tissue at or below the point in its column: it is in a gap of the tissue's
                        // lattice (or between two layers of tissue), not under it
                        inside |= column && along <= 0.0;
                    }
                }
            }
        }
        // no bed under tissue held by a fixed region: what lies between the two would be squeezed
        let pinned = || {
            pins.iter().any(|q| {
                let (along, lateral2, _) = offset(q, p);
                along > 0.0 && in_column(lateral2)
            })
        };
        under && clear && !inside && !pinned()
    };
    points.into_iter().filter(keep).collect()
}

/// Empties the scenario's cavities (SPEC §7.8's pierced capsule) of tissue: every solid particle
/// (capsule included) and the perfusing liquid (`perfusing`: one flag per liquid particle); liquid
/// the scenario places with its own generators stays (a primed needle). Runs after the capsule is
/// built, so the hole's faces get no capsule lining (the needle pierced the capsule; it was not grown
/// around it), and before the bond table is built, so no bond crosses the hole. Returns the positions
/// of the solid particles it removed: the tissue's place, which a tool's walls may take.
fn empty_cavities(g: &mut GeneratedParticles, s: &Scenario, perfusing: &[bool]) -> Vec<V3> {
    if s.cavities.is_empty() {
        return Vec::new();
    }
    let outside = |p: &V3| !s.cavities.iter().any(|r| r.contains(*p, s.dimensions));
    let keep_s: Vec<bool> = g.solid.pos.iter().map(outside).collect();
    let removed = g.solid.pos.iter().zip(&keep_s).filter(|(_, k)| !**k).map(|(p, _)| *p).collect();
    let keep_l: Vec<bool> = (0..g.liquid.pos.len())
        .map(|i| !perfusing.get(i).copied().unwrap_or(false) || outside(&g.liquid.pos[i]))
        .collect();
    g.solid.pos = kept(&g.solid.pos, &keep_s);
    g.solid.vel = kept(&g.solid.vel, &keep_s);
    g.solid.mass = kept(&g.solid.mass, &keep_s);
    g.solid_flags = kept(&g.solid_flags, &keep_s);
    g.solid_liquid_boundary_mass = kept(&g.solid_liquid_boundary_mass, &keep_s);
    g.solid_normal = kept(&g.solid_normal, &keep_s);
    g.liquid.pos = kept(&g.liquid.pos, &keep_l);
    g.liquid.vel = kept(&g.liquid.vel, &keep_l);
    g.liquid.mass = kept(&g.liquid.mass, &keep_l);
    removed
}

/// The lattice cells of the solid particles a cavity removed, hashed by cell for [`TissueSites::covers`].
struct TissueSites {
    dx: f64,
    d: usize,
    cells: std::collections::HashMap<[i64; 3], Vec<V3>>,
}

impl TissueSites {
    fn new(sites: &[V3], dx: f64, d: usize) -> TissueSites {
        let mut cells: std::collections::HashMap<[i64; 3], Vec<V3>> = std::collections::HashMap::new();
        if dx > 0.0 {
            for p in sites {
                cells.entry(Self::key(*p, dx)).or_default().push(*p);
            }
        }
        TissueSites { dx, d, cells }
    }

    fn key(p: V3, dx: f64) -> [i64; 3] {
        [(p[0] / dx).floor() as i64, (p[1] / dx).floor() as i64, (p[2] / dx).floor() as i64]
    }

    /// Whether `p` lies in the lattice cell (the cube of side Δx_s centred on it) of a removed site.
    fn covers(&self, p: V3) -> bool {
        if self.cells.is_empty() {
            return false;
        }
        let half = 0.5 * self.dx * (1.0 + 1e-9);
        let k = Self::key(p, self.dx);
        let span = |a: usize| if a < self.d { -1..=1 } else { 0..=0 };
        span(0).any(|i| {
            span(1).any(|j| {
                span(2).any(|l| {
                    self.cells
                        .get(&[k[0] + i, k[1] + j, k[2] + l])
                        .is_some_and(|v| v.iter().any(|q| (0..self.d).all(|a| (p[a] - q[a]).abs() <= half)))
                })
            })
        })
    }
}

/// The entries of `v` whose `keep` flag is set.
fn kept<T: Copy>(v: &[T], keep: &[bool]) -> Vec<T> {
    v.iter().zip(keep).filter(|(_, k)| **k).map(|(x, _)| *x).collect()
}

/// Lattice offset of a perfused mesh's phases: the solid lattice is cell-centred (offset Δx/2), the
/// liquid lattice sits half a spacing from it, so that the perfusing liquid interleaves with the tissue
/// skeleton instead of sitting on it — and its outer layer lies beneath the capsule, not in it.
pub fn mesh_lattice_offset(phase: Phase, dx: f64) -> V3 {
    match phase {
        Phase::Solid => [0.5 * dx; 3],
        Phase::Liquid => [0.0; 3],
    }
}

/// Depth below the capsule [in units of Δx_s] that a perfusing liquid particle must have at generation.
pub const LIQUID_CAPSULE_SETBACK: f64 = 0.45;

/// Removes the mesh-generated liquid particles (`ranges`) that lie in or outside the capsule layer: a
/// particle is kept only when it is at least [`LIQUID_CAPSULE_SETBACK`]·Δx_s beneath the capsule, measured
/// along the outward normals of the nearest membrane parents. A liquid particle in the membrane plane feels the
/// membrane's repulsion (SPEC §4.1, §4.5: the membrane is the liquid's virtual boundary) only
/// tangentially, while the pressure of the liquid behind it pushes it out: under the weight of the
/// hanging liver such particles leaked through the capsule's flat visceral face at rest. The liquid of
/// the organ is the liquid *enclosed* by the capsule.
fn keep_liquid_beneath_capsule(
    g: &mut GeneratedParticles,
    ranges: &[std::ops::Range<usize>],
    capsule: &[(V3, V3)],
    perfusing: &mut Vec<bool>,
) {
    use std::collections::HashMap;
    if ranges.is_empty() || capsule.is_empty() || g.dx_solid <= 0.0 {
        return;
    }
    let radius = 2.0 * g.h_solid.max(g.h_liquid);
    let cell = |p: &V3| -> [i64; 3] {
        [(p[0] / radius).floor() as i64, (p[1] / radius).floor() as i64, (p[2] / radius).floor() as i64]
    };
    let mut bins: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (k, (p, _)) in capsule.iter().enumerate() {
        bins.entry(cell(p)).or_default().push(k);
    }
    let setback = LIQUID_CAPSULE_SETBACK * g.dx_solid;
    // Depth of x beneath the capsule: the largest depth along the outward normals of the capsule parents
    // nearest to x (those within Δx_s/4 of the nearest, so that lattice ties are all counted — a
    // particle diagonally inside a convex corner is a membrane parent too, §4.5, and sees the liquid of
    // its corner cell outside itself).
    let beneath = |x: &V3| -> bool {
        let c = cell(x);
        let mut near: Vec<(f64, usize)> = Vec::new();
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    for &k in bins.get(&[c[0] + dx, c[1] + dy, c[2] + dz]).into_iter().flatten() {
                        let q = capsule[k].0;
                        let r = (0..3).map(|a| (q[a] - x[a]).powi(2)).sum::<f64>().sqrt();
                        if r < radius {
                            near.push((r, k));
                        }
                    }
                }
            }
        }
        // No capsule particle within the support radius: deep inside.
        let Some(r0) = near.iter().map(|&(r, _)| r).reduce(f64::min) else { return true };
        let depth = near
            .iter()
            .filter(|&&(r, _)| r <= r0 + 0.25 * g.dx_solid)
            .map(|&(_, k)| {
                let (q, n) = capsule[k];
                (0..3).map(|a| (q[a] - x[a]) * n[a]).sum::<f64>()
            })
            .fold(f64::MIN, f64::max);
        depth >= setback
    };
    let in_mesh = |i: usize| ranges.iter().any(|r| r.contains(&i));
    let keep: Vec<bool> = (0..g.liquid.pos.len()).map(|i| !in_mesh(i) || beneath(&g.liquid.pos[i])).collect();
    g.liquid.pos = kept(&g.liquid.pos, &keep);
    g.liquid.vel = kept(&g.liquid.vel, &keep);
    g.liquid.mass = kept(&g.liquid.mass, &keep);
    *perfusing = kept(perfusing, &keep);
}

/// Membrane detection and boundary-resolution enhancement (thesis §3.1.2–3.1.3, SPEC §4.5): marks solid
/// particles whose neighbourhood centre of mass (radius R_s, self included) is offset by more than δ_mem,
/// then adds `count` children per membrane particle on its tangent plane, sharing the parent's mass
/// equally. Returns the membrane flag of every (old and new) solid particle, each membrane parent's position
/// and outward normal, and the lattice site every solid particle belongs to (itself, or a child's parent).
fn add_membrane(g: &mut GeneratedParticles, m: &super::Membrane, d: usize) -> (Vec<bool>, Vec<(V3, V3)>, Vec<usize>) {
    use std::collections::HashMap;
    let radius = 2.0 * g.h_solid;
    let delta = m.threshold * g.dx_solid;
    let pos = g.solid.pos.clone();
    let cell = |p: &V3| -> [i64; 3] {
        [(p[0] / radius).floor() as i64, (p[1] / radius).floor() as i64, (p[2] / radius).floor() as i64]
    };
    let mut bins: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, p) in pos.iter().enumerate() {
        bins.entry(cell(p)).or_default().push(i);
    }
    let nz = if d == 3 { 1 } else { 0 };
    let mut offsets = Vec::new();
    for (i, p) in pos.iter().enumerate() {
        let c = cell(p);
        let (mut sum, mut n) = ([0.0f64; 3], 0usize);
        for dz in -nz..=nz {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if let Some(list) = bins.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                        for &j in list {
                            let q = pos[j];
                            let r2: f64 = (0..3).map(|a| (q[a] - p[a]).powi(2)).sum();
                            if r2 < radius * radius {
                                for a in 0..3 {
                                    sum[a] += q[a];
                                }
                                n += 1;
                            }
                        }
                    }
                }
            }
        }
        let off = [p[0] - sum[0] / n as f64, p[1] - sum[1] / n as f64, p[2] - sum[2] / n as f64];
        let len = (off[0] * off[0] + off[1] * off[1] + off[2] * off[2]).sqrt();
        offsets.push((i, off, len));
    }
    let mut flags = vec![false; pos.len()];
    let mut parent: Vec<usize> = (0..pos.len()).collect();
    let mut capsule = Vec::new();
    let share = 1.0 / (membrane_children(m, d) as f64 + 1.0);
    let r_e = m.radius * g.dx_solid;
    for &(i, off, len) in &offsets {
        if len <= delta {
            continue;
        }
        flags[i] = true;
        let n_hat = [off[0] / len, off[1] / len, off[2] / len];
        capsule.push((pos[i], n_hat));
        let (t1, t2) = tangent_basis(n_hat, d);
        let (vel, mass) = (g.solid.vel[i], g.solid.mass[i] * share);
        g.solid.mass[i] = mass;
        for k in 0..membrane_children(m, d) {
            let theta = if d == 2 {
                std::f64::consts::PI * k as f64
            } else {
                m.angle + 2.0 * std::f64::consts::PI * k as f64 / m.count as f64
            };
            let (c, sn) = if d == 2 { (theta.cos(), 0.0) } else { (theta.cos(), theta.sin()) };
            let p = pos[i];
            g.solid.pos.push([
                p[0] + r_e * (c * t1[0] + sn * t2[0]),
                p[1] + r_e * (c * t1[1] + sn * t2[1]),
                p[2] + r_e * (c * t1[2] + sn * t2[2]),
            ]);
            g.solid.vel.push(vel);
            g.solid.mass.push(mass);
            flags.push(true);
            parent.push(i);
        }
    }
    (flags, capsule, parent)
}

/// Children per membrane particle: N_e in 3-D; in 2-D the "circle" is the two points x ± r_e t1 (SPEC §4.5).
fn membrane_children(m: &super::Membrane, d: usize) -> u32 {
    if d == 2 { m.count.min(2) } else { m.count }
}

/// Deterministic orthonormal basis of the plane ⟂ n̂: t1 = normalise(n̂ × a) with a the coordinate axis
/// least aligned with n̂, t2 = n̂ × t1 (SPEC §4.5). In 2-D, t1 is n̂ rotated by 90° in-plane.
fn tangent_basis(n: V3, d: usize) -> (V3, V3) {
    if d == 2 {
        return ([-n[1], n[0], 0.0], [0.0, 0.0, 0.0]);
    }
    let mut k = 0;
    for a in 1..3 {
        if n[a].abs() < n[k].abs() {
            k = a;
        }
    }
    let mut axis = [0.0; 3];
    axis[k] = 1.0;
    let cross = |u: V3, v: V3| [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    let t = cross(n, axis);
    let l = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
    let t1 = [t[0] / l, t[1] / l, t[2] / l];
    (t1, cross(n, t1))
}

/// Displacement \[m\] and velocity [m/s] of a boundary object at time t (SPEC §4.1).
/// Before t = 0 (relaxation) every object rests at its initial pose.
pub fn motion_at(m: &Motion, t: f64) -> (V3, V3) {
    if t < 0.0 {
        return ([0.0; 3], [0.0; 3]);
    }
    match m {
        Motion::Static => ([0.0; 3], [0.0; 3]),
        Motion::Translate { velocity, start, stop } => {
            let end = stop.unwrap_or(f64::INFINITY);
            let active = (t.min(end) - start).max(0.0);
            let moving = t >= *start && t < end;
            let v = if moving { *velocity } else { [0.0; 3] };
            ([velocity[0] * active, velocity[1] * active, velocity[2] * active], v)
        }
        Motion::Oscillate { amplitude, frequency, phase } => {
            let w = 2.0 * std::f64::consts::PI * frequency;
            let s = (w * t + phase).sin() - phase.sin();
            let c = w * (w * t + phase).cos();
            (
                [amplitude[0] * s, amplitude[1] * s, amplitude[2] * s],
                [amplitude[0] * c, amplitude[1] * c, amplitude[2] * c],
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bed moulded under a 2 × 2 column of solid particles (gravity −y): its points lie under the
    /// column's footprint (less than ¾ of a spacing off it), below it within clearance + depth, at least
    /// `clearance` from every solid particle; nothing beside or above the tissue; no gravity, no bed.
    #[test]
    fn a_moulded_bed_fills_the_space_under_the_tissue() {
        let dx = 0.01;
        // on the bed's cell-centred lattice, so that lattice points lie straight under each particle
        let solid: Vec<V3> = [(0.005, 0.005), (0.005 + dx, 0.005)]
            .iter()
            .flat_map(|&(x, z)| [[x, 0.055, z], [x, 0.055 + dx, z], [x, 0.055, z + dx], [x, 0.055 + dx, z + dx]])
            .collect();
        let box_lattice = lattice_points(&Region::Box { min: [-0.05, -0.05, -0.05], max: [0.06, 0.1, 0.06] }, dx, 3);
        let m = super::super::Mould { clearance: 0.005, depth: 0.03 };
        let free = vec![false; solid.len()];
        let bed = moulded_bed(box_lattice.clone(), &solid, &free, [0.0, -9.81, 0.0], &m, dx);
        assert!(!bed.is_empty() && bed.len() < box_lattice.len());
        for p in &bed {
            let near =
                solid.iter().map(|q| ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2) + (q[2] - p[2]).powi(2)).sqrt());
            assert!(near.fold(f64::INFINITY, f64::min) >= m.clearance, "{p:?} within the clearance");
            assert!(
                p[1] < 0.055 && p[1] >= 0.055 - m.clearance - m.depth,
                "{p:?} not below the tissue within the depth"
            );
            let off = solid.iter().map(|q| (q[0] - p[0]).hypot(q[2] - p[2])).fold(f64::INFINITY, f64::min);
            assert!(off < 0.75 * dx, "{p:?} beside the tissue");
        }
        // every lattice point straight under a solid particle, within the depth, is in the bed
        let mut under = 0;
        for q in &solid {
            for p in &box_lattice {
                let below = q[1] - p[1];
                if (p[0] - q[0]).abs() < 1e-9
                    && (p[2] - q[2]).abs() < 1e-9
                    && p[1] <= 0.055 - m.clearance
                    && below <= 0.03
                {
                    assert!(bed.contains(p), "{p:?} under {q:?} left out");
                    under += 1;
                }
            }
        }
        assert!(under >= 8, "only {under} lattice points checked under the tissue");
        assert!(moulded_bed(box_lattice.clone(), &solid, &free, [0.0; 3], &m, dx).is_empty());
        // a fixed particle atop the first column: no bed under that column, the rest unchanged
        let mut pinned = free.clone();
        pinned[1] = true;
        let q = solid[1];
        let bed_pinned = moulded_bed(box_lattice, &solid, &pinned, [0.0, -9.81, 0.0], &m, dx);
        assert!(bed_pinned.iter().all(|p| (p[0] - q[0]).hypot(p[2] - q[2]) >= 0.75 * dx));
        assert_eq!(bed.iter().filter(|p| (p[0] - q[0]).hypot(p[2] - q[2]) >= 0.75 * dx).count(), bed_pinned.len());
    }
}
