//! Blood drawing with a syringe (thesis §4.2.3, Fig. 4.8; SPEC §7.8): the scenario and its validation
//! case `perfuse validate --case syringe`.
//!
//! SPEC's set-up is given in lattice spacings (needle bore 2Δx_l, barrel 6Δx_l, walls 3 layers of
//! Δx_s/2), so one function writes the scenario for any lattice: `assets/scenarios/syringe.ron` is
//! [`scenario_ron`] at 32³/30³ (a unit test keeps the file and the function equal), and `--quick` and
//! the CI test write a coarser one. The needle and the barrel are square tubes of box-shaped boundary
//! objects (a bore of half-width 2Δx_l instead of a round one of radius 2Δx_l: the lattices are
//! square anyway). The needle's footprint is a `cavity`: the needle pierced the capsule, so neither
//! tissue, capsule nor perfusing blood remains in it, and no bond crosses it.
//!
//! The suction is a pressure outlet (scenario `outlets`; README: deviations from SPEC) whose buffer is
//! the needle's bore, primed with pure blood (n₀ = 1): its blood shows the tissue's blood at the tip
//! the syringe's −5 kPa, feels no force, and moves up the bore as the blood at the tip does, into a sink
//! where the bore opens into the barrel. SPEC's suction disc over a sink at the barrel's top needed a
//! primed column of blood under tension from the disc down to the tip, and an SPH column under tension
//! parts: the primed barrel was sucked into the sink within 0.05 s and the draw stopped (README:
//! `syringe.ron` under Validation). The barrel stays, closed by a plain plunger where the disc was. Only
//! the tissue's blood within [`TIP_TENSION_RADIUS`] of the tip (`liquid_tension_in`) may take tension,
//! so that the suction reaches into the tissue, while the blood by the capsule keeps (2.53)'s clamp at
//! 0: with tension everywhere the perfused tissue's blood went into SPH's tensile instability and burst
//! through the capsule.
//!
//! Acceptance (SPEC §7.8): (1) the drawn volume — liquid sunk plus liquid in the needle's bore and the
//! barrel, less what was there at t = 0 — never falls between 0.05-s bins after
//! 0.1 s and exceeds 0.5 % of the specimen's liquid volume at the end; (2) the solid within 3Δx_s of
//! the needle tip moves toward the tip on average; (3) liquid outside the tissue and outside the
//! syringe stays ≤ 1 % of the liquid.

use super::frames::simulation_with_frames;
use super::plot::{Chart, Series};
use super::relaxation::RelaxWith;
use super::validate::{CaseResult, Invariants, Pace, ValidationError, advance_to, at_least, at_most, plot_into};
use crate::sim::{BackendKind, State};
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

/// The shipped scenario (32³ solid, 30³ liquid).
pub const SYRINGE: &str = include_str!("../../assets/scenarios/syringe.ron");
/// Cube side L_c \[m\] (SPEC §7.5's specimen).
pub const L_C: f64 = 0.05;
/// Suction \[Pa\] (SPEC §7.8's disc; here the outlet's gauge pressure in the needle's bore).
pub const SUCTION: f64 = -5000.0;
/// Radius \[m\] of the tissue around the needle tip whose blood may take tension (`liquid_tension_in`):
/// L_c/5, 6.7 mm clear of the capsule's top face (L_c/3 above the tip).
pub const TIP_TENSION_RADIUS: f64 = L_C / 5.0;
/// Depth of the sink above the bore's top \[Δx_l\] (SPEC §7.8: 2 below the disc).
pub const SINK_DEPTH: f64 = 0.5;

/// SPEC §7.8's syringe for an ns³ solid / nl³ liquid specimen (all lengths in metres, scenario
/// coordinates: the specimen fills [−L_c/2, L_c/2]² × [0, L_c], the needle's axis is x = y = 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Geometry {
    pub dx_s: f64,
    pub dx_l: f64,
    /// Wall thickness: 3 layers at Δx_b = Δx_s/2.
    pub wall: f64,
    /// Half-widths of the needle's bore and outside, and of the barrel's inside and outside.
    pub bore: f64,
    pub needle_out: f64,
    pub barrel_in: f64,
    pub barrel_out: f64,
    /// Needle tip (L_c/3 below the top face), barrel bottom (L_c + 2 mm), suction disc (L_c + 25 mm)
    /// and barrel top (L_c + 30 mm) heights.
    pub z_tip: f64,
    pub z_bottom: f64,
    pub z_disc: f64,
    pub z_top: f64,
    /// Top of the bore, where it opens into the barrel: the outlet's buffer ends and the sink begins.
    pub z_sink: f64,
}

impl Geometry {
    pub fn new(ns: u32, nl: u32) -> Geometry {
        let (dx_s, dx_l) = (L_C / f64::from(ns), L_C / f64::from(nl));
        let wall = 1.5 * dx_s;
        let (bore, barrel_in) = (2.0 * dx_l, 6.0 * dx_l);
        Geometry {
            dx_s,
            dx_l,
            wall,
            bore,
            needle_out: bore + wall,
            barrel_in,
            barrel_out: barrel_in + wall,
            z_tip: L_C - L_C / 3.0,
            z_bottom: L_C + 0.002,
            z_disc: L_C + 0.025,
            z_top: L_C + 0.030,
            z_sink: L_C + 0.002 + wall,
        }
    }

    /// At the needle: within `reach` of its outside, from `reach` below its tip up (the bore's mouth,
    /// and the capsule's hole around the shaft), where blood outside the tissue has not leaked
    /// "elsewhere" (SPEC §7.8 (3)).
    pub fn at_needle(&self, p: [f64; 3], reach: f64) -> bool {
        let h = self.needle_out + reach;
        p[0].abs() <= h && p[1].abs() <= h && p[2] >= self.z_tip - reach
    }

    /// The needle tip: the centre of the bore's lower end.
    pub fn tip(&self) -> [f64; 3] {
        [0.0, 0.0, self.z_tip]
    }

    /// Inside the syringe: the needle's bore above its tip, or the barrel between its bottom and the disc.
    pub fn inside(&self, p: [f64; 3]) -> bool {
        let within = |h: f64| p[0].abs() <= h && p[1].abs() <= h;
        (within(self.bore) && p[2] >= self.z_tip && p[2] <= self.z_bottom + self.wall)
            || (within(self.barrel_in) && p[2] >= self.z_bottom && p[2] <= self.z_disc)
    }

    /// The boundary objects: (name, min, max); the plunger (SPEC's suction disc, here a plain wall) is the last.
    fn boxes(&self) -> Vec<(String, [f64; 3], [f64; 3])> {
        let (a, n, ai, ao, w) = (self.bore, self.needle_out, self.barrel_in, self.barrel_out, self.wall);
        // Four walls of a square tube between half-widths `inner` and `outer` over z0..z1.
        let tube = |name: &str, inner: f64, outer: f64, z0: f64, z1: f64| {
            vec![
                (format!("{name} +x"), [inner, -outer, z0], [outer, outer, z1]),
                (format!("{name} -x"), [-outer, -outer, z0], [-inner, outer, z1]),
                (format!("{name} +y"), [-inner, inner, z0], [inner, outer, z1]),
                (format!("{name} -y"), [-inner, -outer, z0], [inner, -inner, z1]),
            ]
        };
        let mut b = tube("needle", a, n, self.z_tip, self.z_bottom + w);
        // The barrel's floor: a square ring from the needle's outside to the barrel's inside.
        b.extend(tube("barrel floor", n, ai, self.z_bottom, self.z_bottom + w));
        b.extend(tube("barrel", ai, ao, self.z_bottom, self.z_top));
        b.push(("plunger".into(), [-ai, -ai, self.z_disc], [ai, ai, self.z_disc + w]));
        b
    }
}

/// The scenario text for an ns³ solid / nl³ liquid specimen with SPEC §7.8's syringe, relaxed as
/// SPEC §7.5's specimen, for `duration` seconds.
pub fn scenario_ron(ns: u32, nl: u32, duration: f64) -> String {
    let g = Geometry::new(ns, nl);
    // Unrounded: a wall 3Δx_b thick rounded down by 0.1 µm would get 2 lattice layers, not 3.
    let r = |x: f64| x;
    let v = |p: [f64; 3]| format!("({:?}, {:?}, {:?})", r(p[0]), r(p[1]), r(p[2]));
    let mut s = String::new();
    let _ = write!(
        s,
        "// Blood drawing with a syringe (thesis §4.2.3, Fig. 4.8; SPEC.md §7.8), written by\n\
         // `perfuse::analysis::syringe::scenario_ron({ns}, {nl}, {duration:?})`: SPEC §7.5's membrane-enclosed specimen\n\
         // ({ns}³ solid, {nl}³ liquid, C10 = 100 kPa, C01 = 0.4 kPa, k_s = k_sat = 1e5 Pa, η = 0.35 Pa·s, on a plate,\n\
         // gravity, relaxed) with a needle through its capsule: a square tube of boundary particles (bore half-width\n\
         // 2Δx_l, walls 3 layers at Δx_s/2), its tip L_c/3 below the top face, its footprint a `cavity` (the needle\n\
         // pierced the capsule: no tissue, capsule, perfusing blood or bond is left in or across it). Above, the\n\
         // barrel (half-width 6Δx_l, z = L_c + 2 mm … L_c + 30 mm, closed at the bottom but for the needle's bore,\n\
         // and at z = L_c + 25 mm by the plunger). The suction (−5 kPa) is an outlet: the needle's bore, primed\n\
         // with pure blood (fraction 1), is its buffer, whose blood shows the tissue's blood at the tip the\n\
         // syringe's pressure, feels no force and moves up the bore as the blood below it does, into a sink\n\
         // where the bore opens into the barrel (README: \"Pressure outlets\"; SPEC §7.8's disc over a sink\n\
         // parts a column of blood under tension). The suction is held while the specimen relaxes and draws\n\
         // from t = 0. Units: SI.\n"
    );
    let _ = writeln!(s, "Scenario(");
    let _ = writeln!(s, "    name: \"syringe\",");
    let _ = writeln!(
        s,
        "    description: \"A syringe draws blood from the membrane-enclosed perfused specimen (SPEC §7.8)\","
    );
    let _ = writeln!(s, "    dimensions: 3,");
    let _ = writeln!(s, "    domain: Domain(min: (-0.08, -0.08, -0.02), max: (0.08, 0.08, {})),", L_C + 0.04);
    let _ = writeln!(s, "    gravity: (0.0, 0.0, -9.81),");
    let _ = writeln!(s, "    liquid: Some(Liquid(density: 1000.0, viscosity: 0.35, stiffness: Some(1.0e5))),");
    let _ = writeln!(
        s,
        "    solid: Some(Solid(density: 1000.0, c10: 1.0e5, c01: 400.0, k_s: 1.0e5, n_sat: 0.6, k_sat: 1.0e5, friction: 1.0e6)),"
    );
    let _ = writeln!(s, "    numerics: Numerics(");
    let _ = writeln!(s, "        dx_solid: Some({:?}),", r(g.dx_s));
    let _ = writeln!(s, "        dx_liquid: Some({:?}),", r(g.dx_l));
    let _ = writeln!(s, "        h_over_dx: 1.3,");
    let _ = writeln!(s, "        h_liquid: Some({:?}), // one global h = 1.3Δx_s (SPEC §7.5)", r(1.3 * g.dx_s));
    let _ = writeln!(
        s,
        "        artificial_viscosity: ArtificialViscosity(alpha: 1.0, beta: 1.0, gamma: 0.01, liquid: false),"
    );
    let _ = writeln!(s, "        artificial_stress: ArtificialStress(epsilon: 0.3, exponent: 4),");
    let _ = writeln!(s, "        xsph: Xsph(solid: 0.5, liquid: 0.0),");
    let _ = writeln!(
        s,
        "        // the suction reaches into the tissue through its blood around the tip, which may take tension\n\
         \x20       // (SPEC (2.53) unclamped) within L_c/5 of the tip; not the blood by the capsule, where tension bursts\n\
         \x20       // it out (README: syringe.ron under Validation)"
    );
    let _ = writeln!(s, "        liquid_tension: true,");
    let _ =
        writeln!(s, "        liquid_tension_in: [Sphere(centre: {}, radius: {:?})],", v(g.tip()), TIP_TENSION_RADIUS);
    let _ = writeln!(s, "        dt_min: 1e-9,");
    let _ = writeln!(s, "        dt_max: 1e-3,");
    let _ = writeln!(s, "    ),");
    let h = 0.5 * L_C;
    let _ = writeln!(s, "    particles: [");
    let _ = writeln!(
        s,
        "        PerfusedBlock(min: {}, max: {}, solid_fraction: 0.6, liquid_fraction: 0.4),",
        v([-h, -h, 0.0]),
        v([h, h, L_C])
    );
    let _ = writeln!(s, "        // the primed needle: pure blood in the bore (the outlet's buffer)");
    let _ = writeln!(
        s,
        "        Box(phase: Liquid, min: {}, max: {}, fraction: 1.0),",
        v([-g.bore, -g.bore, g.z_tip]),
        v([g.bore, g.bore, g.z_sink])
    );
    let _ = writeln!(s, "    ],");
    let _ = writeln!(s, "    boundaries: [");
    let _ = writeln!(
        s,
        "        Boundary(name: \"plate\", shape: Box(min: (-0.075, -0.075, {:?}), max: (0.075, 0.075, 0.0)), spacing: Some({:?})),",
        r(-3.0 * g.dx_s),
        r(g.dx_s)
    );
    let spacing = r(0.5 * g.dx_s);
    let boxes = g.boxes();
    for (name, min, max) in boxes {
        let _ = writeln!(
            s,
            "        Boundary(name: \"{name}\", shape: Box(min: {}, max: {}), spacing: Some({spacing:?})),",
            v(min),
            v(max)
        );
    }
    let _ = writeln!(s, "    ],");
    let _ = writeln!(
        s,
        "    outlets: [ Outlet(name: \"syringe\", region: Box(min: {}, max: {}), pressure: {SUCTION:?}, normal: (0.0, 0.0, 1.0)) ],",
        v([-g.bore, -g.bore, g.z_tip]),
        v([g.bore, g.bore, g.z_sink])
    );
    let _ = writeln!(
        s,
        "    cavities: [ Box(min: {}, max: {}) ],",
        v([-g.needle_out, -g.needle_out, g.z_tip]),
        v([g.needle_out, g.needle_out, g.z_bottom])
    );
    let _ = writeln!(
        s,
        "    sinks: [ Sink(name: \"barrel\", region: Box(min: {}, max: {})) ],",
        v([-g.barrel_in, -g.barrel_in, g.z_sink]),
        v([g.barrel_in, g.barrel_in, g.z_sink + SINK_DEPTH * g.dx_l])
    );
    let _ =
        writeln!(s, "    membrane: Some(Membrane(threshold: 0.5, count: 3, radius: 0.5, angle: 0.7853981633974483)),");
    // the primed syringe settles with the specimen, its suction held, and draws from t = 0
    let _ = writeln!(
        s,
        "    relaxation: Some(Relaxation(duration: 0.3, damping: 20.0, gravity_solid_only: true, hold_suction: true)),"
    );
    let _ = writeln!(s, "    duration: {duration:?},");
    let _ = writeln!(s, "    output: Output(frame_interval: Some(0.05)),");
    let _ = writeln!(s, ")");
    s
}

/// What one run measured (SPEC §7.8's quantities).
#[derive(Clone, Debug, Default)]
pub struct SyringeOutcome {
    pub resolution: String,
    /// Liquid volume of the specimen (outside the syringe) at t = 0 \[m³\].
    pub liquid_volume: f64,
    /// (t, drawn volume \[m³\]) every 0.05 s.
    pub drawn: Vec<(f64, f64)>,
    /// Largest fall of the drawn volume between samples after the settling time \[m³\].
    pub drawn_largest_drop: f64,
    /// Solid particles within 3Δx_s of the tip at t = 0, and their mean displacement toward it \[m\].
    pub near_tip: usize,
    pub toward_tip: f64,
    /// Largest liquid fraction outside the tissue, outside the syringe and away from the needle (more
    /// than R from it) over the run.
    pub leaked_max: f64,
    pub invariants_failed: usize,
    /// The bore's liquid fraction ([`bore_fill`], whole and lower half) at the end and the whole bore's
    /// least over the run (a diagnostic of the outlet's buffer, not a SPEC row).
    pub bore_fill_end: (f64, f64),
    pub bore_fill_min: f64,
}

/// Volume Σ m/ρ₀ of the liquid particles for which `keep` holds (given their scenario position).
fn liquid_volume(p: &crate::sim::params::Params, s: &State, keep: impl Fn(usize, [f64; 3]) -> bool) -> f64 {
    (0..s.liquid.len())
        .filter(|&i| keep(i, p.to_world(s.liquid.pos[i])))
        .map(|i| f64::from(s.liquid.mass[i]) / f64::from(p.rho0_l))
        .sum()
}

/// Liquid particle `i` at world position `x` has leaked: outside the tissue (it sees almost no solid),
/// outside the syringe and farther than `reach` from the needle.
fn leaked_at(g: &Geometry, s: &State, i: usize, x: [f64; 3], reach: f64) -> bool {
    s.liquid.n_s[i] < crate::sim::state::LIQUID_OUTSIDE_NS && !g.inside(x) && !g.at_needle(x, reach)
}

/// Where the leaked blood is (a diagnostic log line): how many particles, how many of them primed blood
/// from the syringe (fraction 1, so a mass of at least 0.7ρ₀Δx_l³) and how many perfusing blood from the
/// tissue, and the leaked particles' mean position and height range (world, mm) — below the specimen's
/// top (oozing through the capsule) or above it (along the needle's shaft or out of the barrel).
fn log_leak(name: &str, g: &Geometry, p: &crate::sim::params::Params, s: &State, reach: f64) {
    let (mut n, mut primed, mut sum, mut z_lo, mut z_hi) = (0usize, 0usize, [0.0f64; 3], f64::INFINITY, f64::MIN);
    for i in 0..s.liquid.len() {
        let x = p.to_world(s.liquid.pos[i]);
        if leaked_at(g, s, i, x, reach) {
            n += 1;
            primed += usize::from(is_primed(p, s, i));
            (0..3).for_each(|a| sum[a] += x[a]);
            z_lo = z_lo.min(x[2]);
            z_hi = z_hi.max(x[2]);
        }
    }
    if n > 0 {
        let c = sum.map(|v| v / n as f64 * 1e3);
        log::info!(
            "{name}: leaked {n} particles ({primed} primed, {} perfusing), mean at ({:.1}, {:.1}, {:.1}) mm, z {:.1} … {:.1} mm",
            n - primed,
            c[0],
            c[1],
            c[2],
            z_lo * 1e3,
            z_hi * 1e3
        );
    }
}

/// Liquid particle `i` is primed blood from the syringe (fraction 1: a mass of at least 0.7ρ₀Δx_l³;
/// the tissue's perfusing blood carries its fraction 0.4).
fn is_primed(p: &crate::sim::params::Params, s: &State, i: usize) -> bool {
    f64::from(s.liquid.mass[i]) >= 0.7 * f64::from(p.rho0_l) * f64::from(p.dx_liquid).powi(3)
}

/// What is in the syringe (a diagnostic log line): primed and perfusing particles in the bore (below
/// the barrel's floor) and in the barrel, and the particles sunk so far: where a change of the drawn
/// volume comes from (one primed particle across the tip's plane is Δx_l³ of it); and the bore's
/// liquid fraction, whole and lower half ([`bore_fill`]).
fn log_syringe(
    name: &str,
    g: &Geometry,
    p: &crate::sim::params::Params,
    sim: &crate::sim::Simulation,
    s: &State,
    (whole, lower): (f64, f64),
) {
    let mut n = [[0usize; 2]; 2];
    for i in 0..s.liquid.len() {
        let x = p.to_world(s.liquid.pos[i]);
        if g.inside(x) {
            n[usize::from(x[2] >= g.z_bottom)][usize::from(!is_primed(p, s, i))] += 1;
        }
    }
    let sunk = sim.emit_totals().map_or(0, |e| e.sunk);
    log::info!(
        "{name}: bore {} primed + {} perfusing, barrel {} primed + {} perfusing, {sunk} sunk; the bore's liquid \
         fraction {whole:.2} (lower half {lower:.2})",
        n[0][0],
        n[0][1],
        n[1][0],
        n[1][1]
    );
}

/// The bore's liquid fraction: the liquid volume Σ m/ρ₀ of the particles in the bore (from the tip to
/// the sink) over the bore's volume, for the whole bore and for its lower half (the rows the blood at the
/// mouth sees). By mass, not by particles: primed blood (fraction 1) and the tissue's blood (fraction
/// n₀ˡ = 0.4, so 0.4 of the mass) fill the bore at rest density with 1× and 2.5× the lattice's number of
/// particles; and by halves, not by slabs Δx_l thick, whose bounds split lattice rows (0 and 2 at t = 0).
/// Returns (whole, lower half): 1 full at rest density, below 1 the buffer has gaps.
pub fn bore_fill(g: &Geometry, p: &crate::sim::params::Params, s: &State) -> (f64, f64) {
    let len = g.z_sink - g.z_tip;
    let in_bore = |x: [f64; 3]| x[0].abs() <= g.bore && x[1].abs() <= g.bore && x[2] >= g.z_tip && x[2] <= g.z_sink;
    let whole = liquid_volume(p, s, |_, x| in_bore(x));
    let lower = liquid_volume(p, s, |_, x| in_bore(x) && x[2] < g.z_tip + 0.5 * len);
    let volume = (2.0 * g.bore).powi(2) * len;
    (whole / volume, 2.0 * lower / volume)
}

/// Volume of the liquid outside the syringe: the specimen's blood, and any that left it elsewhere.
/// What it loses was drawn (the primed blood, whose particles carry more mass, starts inside and is
/// sunk from inside, so it never counts).
fn outside_syringe(g: &Geometry, p: &crate::sim::params::Params, s: &State) -> f64 {
    liquid_volume(p, s, |_, x| !g.inside(x))
}

/// Runs `sc` (a [`scenario_ron`] scenario for the lattice of `g`): relaxation, then the drawing, sampled
/// every `sample` seconds; the drawn volume must not fall from `settle` seconds on (SPEC: 0.05 and
/// 0.1). With `frames` = (dir, prefix), renders `<prefix>_start.png` and `<prefix>_end.png`.
pub fn run(
    sc: &crate::scenario::Scenario,
    g: &Geometry,
    backend: BackendKind,
    frames: Option<(&Path, &str)>,
    (sample, settle): (f64, f64),
    relax: RelaxWith<'_>,
) -> Result<SyringeOutcome, ValidationError> {
    let (mut sim, mut frames) = simulation_with_frames(sc, backend, frames)?;
    super::relaxation::relax_cached(relax, sc, &mut sim)?;
    if let Some(f) = &mut frames {
        f.shoot(&sim, "start");
    }
    let p = sim.params().clone();
    let world = |x: glam::Vec3| p.to_world(x);
    let s0 = sim.read_state()?;
    let outside0 = outside_syringe(g, &p, &s0);
    let tip = glam::DVec3::from(g.tip());
    // the kernel support R = 2h of the solid: blood this close to the needle is at its mouth or shaft
    let reach = 2.0 * f64::from(p.k_solid.h);
    let near: Vec<usize> = (0..s0.solid.len())
        .filter(|&i| (glam::DVec3::from(world(s0.solid.pos[i])) - tip).length() <= 3.0 * g.dx_s)
        .collect();
    let mut out = SyringeOutcome {
        resolution: format!("{} solid + {} liquid, dx_s {:.2} mm", s0.solid.len(), s0.liquid.len(), p.dx_solid * 1e3),
        liquid_volume: outside0,
        near_tip: near.len(),
        bore_fill_min: bore_fill(g, &p, &s0).0,
        ..Default::default()
    };
    let mut inv = Invariants::with_emitters();
    inv.check(&sim, &s0);
    let mut s = s0.clone();
    let mut k = 1u32;
    let mut pace = Pace::new(&sim);
    while sim.time() < sc.duration - 1e-9 {
        let target = (f64::from(k) * sample).min(sc.duration);
        let t = advance_to(&mut sim, target)?;
        if t < target - 1e-9 {
            continue;
        }
        s = sim.read_state()?;
        inv.check(&sim, &s);
        pace.log(&sc.name, &sim);
        let drawn = outside0 - outside_syringe(g, &p, &s);
        out.drawn.push((t, drawn));
        let leaked = liquid_volume(&p, &s, |i, x| leaked_at(g, &s, i, x, reach));
        out.leaked_max = out.leaked_max.max(leaked / out.liquid_volume.max(f64::MIN_POSITIVE));
        log::info!("{}: t = {t:.3} s, drawn {drawn:.3e} m³, leaked {leaked:.2e} m³", sc.name);
        log_leak(&sc.name, g, &p, &s, reach);
        let fill = bore_fill(g, &p, &s);
        log_syringe(&sc.name, g, &p, &sim, &s, fill);
        out.bore_fill_end = fill;
        out.bore_fill_min = out.bore_fill_min.min(fill.0);
        k += 1;
    }
    if let Some(f) = &mut frames {
        f.shoot(&sim, "end");
    }
    let after: Vec<f64> = out.drawn.iter().filter(|(t, _)| *t >= settle - 1e-9).map(|&(_, v)| v).collect();
    out.drawn_largest_drop =
        if after.len() < 2 { f64::NAN } else { after.windows(2).map(|w| w[0] - w[1]).fold(f64::MIN, f64::max) };
    out.toward_tip = near
        .iter()
        .map(|&i| {
            let x0 = glam::DVec3::from(world(s0.solid.pos[i]));
            let x1 = glam::DVec3::from(world(s.solid.pos[i]));
            (x1 - x0).dot((tip - x0).normalize_or_zero())
        })
        .sum::<f64>()
        / near.len().max(1) as f64;
    out.invariants_failed = inv.count();
    Ok(out)
}

/// Rows of `report.json` (SPEC §7.8 (1)–(3) and the invariants).
pub fn rows(o: &SyringeOutcome, wall: f64) -> Vec<CaseResult> {
    let (n, r) = ("syringe", o.resolution.as_str());
    let end = o.drawn.last().map_or(f64::NAN, |&(_, v)| v);
    vec![
        at_most(n, r, "drawn_volume_largest_bin_drop_m3", o.drawn_largest_drop, 0.0, wall),
        at_least(
            n,
            r,
            "drawn_volume_end_over_liquid_volume",
            end / o.liquid_volume.max(f64::MIN_POSITIVE),
            0.005,
            wall,
        ),
        at_least(n, r, "near_tip_mean_displacement_toward_tip_m", o.toward_tip, f64::MIN_POSITIVE, wall),
        at_most(n, r, "leaked_liquid_fraction_max", o.leaked_max, 0.01, wall),
        at_most(n, r, "invariant_violations", o.invariants_failed as f64, 0.0, wall),
    ]
}

/// SPEC §7.8 on `syringe.ron` (quick: a 12³/11³ specimen).
pub fn validate(
    quick: bool,
    backend: BackendKind,
    out: &Path,
    _progress: bool,
    overrides: &[String],
    relax: RelaxWith<'_>,
) -> Result<Vec<CaseResult>, ValidationError> {
    let started = Instant::now();
    let (ns, nl) = if quick { (12, 11) } else { (32, 30) };
    let text = if quick { scenario_ron(ns, nl, 2.0) } else { SYRINGE.to_string() };
    let sc = crate::scenario::Scenario::from_str_with_overrides(&text, "assets/scenarios/syringe.ron", overrides)?;
    let g = Geometry::new(ns, nl);
    let o = run(&sc, &g, backend, Some((out, "syringe")), (0.05, 0.1), relax)?;
    plot_into(
        out,
        "syringe.png",
        &Chart {
            title: "Syringe (thesis section 4.2.3): volume drawn from the specimen",
            x_label: "t [s]",
            y_label: "drawn volume / specimen liquid volume",
            series: vec![Series {
                label: "drawn volume / liquid volume".into(),
                points: o.drawn.iter().map(|&(t, v)| (t, v / o.liquid_volume.max(f64::MIN_POSITIVE))).collect(),
                markers: true,
            }],
        },
    )?;
    Ok(rows(&o, started.elapsed().as_secs_f64()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `assets/scenarios/syringe.ron` is `scenario_ron(32, 30, 2.0)`; run with PERFUSE_BLESS=1 to rewrite it.
    #[test]
    fn shipped_file_is_the_generated_scenario() {
        let text = scenario_ron(32, 30, 2.0);
        if std::env::var_os("PERFUSE_BLESS").is_some() {
            std::fs::write(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/scenarios/syringe.ron"), &text)
                .expect("write syringe.ron");
        }
        assert_eq!(
            SYRINGE, text,
            "assets/scenarios/syringe.ron differs from scenario_ron(32, 30, 2.0): rerun with PERFUSE_BLESS=1"
        );
    }

    /// The objects tile the syringe without overlapping, and the bore and barrel are open to each other.
    #[test]
    fn syringe_geometry() {
        let g = Geometry::new(32, 30);
        let b = g.boxes();
        assert_eq!(b.len(), 13);
        let overlap = |a: &([f64; 3], [f64; 3]), c: &([f64; 3], [f64; 3])| {
            (0..3).all(|k| a.0[k] < c.1[k] - 1e-12 && c.0[k] < a.1[k] - 1e-12)
        };
        for i in 0..b.len() {
            for j in i + 1..b.len() {
                assert!(!overlap(&(b[i].1, b[i].2), &(b[j].1, b[j].2)), "{} overlaps {}", b[i].0, b[j].0);
            }
        }
        // a point on the axis from the tip to the disc is inside the syringe and in no object
        for k in 0..=20 {
            let z = g.z_tip + 1e-6 + (g.z_disc - g.z_tip - 2e-6) * f64::from(k) / 20.0;
            let p = [0.0, 0.0, z];
            assert!(g.inside(p));
            assert!(b.iter().all(|(_, lo, hi)| !(0..3).all(|a| p[a] >= lo[a] && p[a] <= hi[a])), "z = {z}");
        }
        let sc = crate::scenario::Scenario::from_str_with_overrides(SYRINGE, "syringe.ron", &[]).expect("valid");
        assert_eq!(sc.boundaries.len(), 14);
        // every wall is 3 layers thick (SPEC §7.8), the needle's +x wall across x
        let particles = crate::scenario::generate(&sc);
        let mut xs: Vec<i64> = (0..particles.boundary_pos.len())
            .filter(|&i| particles.boundary_object[i] == 1)
            .map(|i| (particles.boundary_pos[i][0] * 1e9).round() as i64)
            .collect();
        xs.sort_unstable();
        xs.dedup();
        assert_eq!(xs.len(), 3, "needle wall layers");
        // no material in the needle's walls, no tissue in its bore; the syringe is primed with pure
        // blood (its particles carry 1/0.4 the mass of the perfusing blood's)
        let in_wall = |p: &[f64; 3]| b[..4].iter().any(|(_, lo, hi)| (0..3).all(|a| p[a] >= lo[a] && p[a] <= hi[a]));
        assert!(particles.solid.pos.iter().all(|p| !in_wall(p) && !g.inside(*p)));
        assert!(particles.liquid.pos.iter().all(|p| !in_wall(p)));
        let primed: Vec<usize> =
            (0..particles.liquid.pos.len()).filter(|&i| g.inside(particles.liquid.pos[i])).collect();
        assert!(primed.len() > 100, "{} primed", primed.len());
        for &i in &primed {
            assert!((particles.liquid.mass[i] / particles.mass_liquid - 2.5).abs() < 1e-9);
        }
    }
}
