//! Pressure outlets and the ambient pressure (README: "Pressure outlets", deviations from SPEC): a
//! suction drawn through an outlet buffer is a lower pressure, not a tension, so an SPH column under it
//! keeps its continuity. Reference: a sealed column (`docs/outlet_column.ron`: nothing can flow in)
//! under a −5 kPa outlet expands to the outlet's pressure, loses only what that expansion pushes into
//! the sink, and rests — where the same column under SPEC D-23's prescribed-pressure disc with tension
//! (`docs/sealed_column.ron`) drains completely within 0.09 s.
//! And continuity across the buffer's face: blood drained out of a porous skeleton at nˡ = 0.4 keeps a
//! pure-liquid buffer nearly full only if the buffer carries off its mass flux, not its velocity.

use perfuse::scenario::Scenario;
use perfuse::sim::{BackendKind, Simulation};

fn column() -> Scenario {
    Scenario::from_str_with_overrides(include_str!("../docs/outlet_column.ron"), "docs/outlet_column.ron", &[])
        .expect("the outlet column is valid")
}

/// The sealed column at −5 kPa gauge through its outlet (CPU, 0.15 s). Reference: the open liquid below
/// the buffer rests at the outlet's pressure plus its hydrostatic head, p_a − 5 kPa + ρg·(mean depth
/// below the buffer), within 5 % of the suction; what it loses to the sink is what the expansion pushes
/// there (at most 10 % of the column: the expansion by 5 kPa/k = 5 % plus the first surge); from 0.1 s
/// nothing more leaves (the column holds), and from 0.15 s the open liquid's mean speed is below
/// 1.5 cm/s (SPH's jitter; a parting column streams at ≈ 10 cm/s). No particle leaves the tube.
#[test]
fn a_sealed_column_under_an_outlet_rests_at_the_prescribed_pressure() {
    let sc = column();
    let mut sim = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
    let n0 = sim.read_state().expect("state").liquid.len();
    let (ambient, suction, buffer_floor) = (1.0e4, -5000.0, 0.0165);
    let (rho0, g) = (1000.0, 9.81);
    let mut counts = Vec::new();
    for k in 1..=3 {
        sim.advance_until(0.05 * k as f64, u64::MAX, |_| {}).expect("run");
        let st = sim.read_state().expect("state");
        let world: Vec<[f64; 3]> = st.liquid.pos.iter().map(|x| sim.params().to_world(*x)).collect();
        let open: Vec<usize> = (0..world.len()).filter(|&i| world[i][2] < buffer_floor).collect();
        let p_mean = open.iter().map(|&i| f64::from(st.liquid.p[i])).sum::<f64>() / open.len() as f64;
        let depth = open.iter().map(|&i| buffer_floor - world[i][2]).sum::<f64>() / open.len() as f64;
        let expected = ambient + suction + rho0 * g * depth;
        let speed = open.iter().map(|&i| f64::from(st.liquid.vel[i].length())).sum::<f64>() / open.len() as f64;
        let outside = world.iter().filter(|w| w[0].abs() > 0.005 + 1e-6 || w[1].abs() > 0.005 + 1e-6 || w[2] < -1e-6);
        eprintln!(
            "t = {:.2} s: {} of {n0} particles left, {} in the open liquid at mean p {p_mean:.0} Pa (expected \
             {expected:.0}: gauge {:.0} against {:.0}), mean speed {:.2e} m/s",
            st.t,
            st.liquid.len(),
            open.len(),
            p_mean - ambient,
            expected - ambient,
            speed
        );
        assert_eq!(outside.count(), 0, "liquid left the tube");
        if k >= 2 {
            assert!(
                (p_mean - expected).abs() <= 0.05 * suction.abs(),
                "the open liquid is not at the outlet's pressure"
            );
        }
        if k >= 3 {
            assert!(speed <= 0.015, "the open liquid is not at rest");
        }
        counts.push(st.liquid.len());
    }
    let lost = n0 - counts[2];
    assert!(lost >= 1, "the suction drew nothing");
    assert!(lost as f64 <= 0.1 * n0 as f64, "the column lost {lost} of {n0}");
    assert_eq!(counts[1], counts[2], "the column still drains after 0.1 s: {counts:?}");
}

/// A 2-D porous channel drained into a pressure outlet: a fixed skeleton (nˢ = 0.6, K̄ = 14 000 Pa·s/m²)
/// from x = 0 to 20 mm perfused with liquid at nˡ = 0.4 (the tissue's fractions, its particles carrying
/// 0.4ρ₀/S_W each), driven along +x by a body acceleration f; the buffer (pure liquid, 0 Pa gauge)
/// from 20 to 26 mm, the sink beyond, walls above and below and behind.
fn porous_channel_into_an_outlet() -> Scenario {
    let text = r#"Scenario(
    name: "porous channel into an outlet",
    dimensions: 2,
    domain: Domain(min: (-0.002, -0.002, 0.0), max: (0.03, 0.007, 0.0)),
    gravity: (20.0, 0.0, 0.0),
    liquid: Some(Liquid(density: 1000.0, viscosity: 0.35, sound_speed: Some(1.0))),
    solid: Some(Solid(density: 1000.0, c10: 0.0, c01: 0.0, k_s: 1.0, n_sat: 0.6, k_sat: 1000.0, friction: 14000.0)),
    numerics: Numerics(dx_liquid: Some(5.0e-4), dx_solid: Some(5.0e-4), h_over_dx: 1.3,
        xsph: Xsph(solid: 0.0, liquid: 0.0), dt_min: 1e-9, dt_max: 1e-3),
    particles: [
        Box(phase: Liquid, min: (0.0, 0.0, 0.0), max: (0.02, 0.005, 0.0), fraction: 0.4),
        Box(phase: Solid, min: (0.0, 0.0, 0.0), max: (0.02, 0.005, 0.0), fraction: 0.6),
        Box(phase: Liquid, min: (0.02, 0.0, 0.0), max: (0.026, 0.005, 0.0), fraction: 1.0),
    ],
    boundaries: [
        Boundary(name: "bottom", shape: Box(min: (-0.0015, -0.0015, 0.0), max: (0.026, 0.0, 0.0))),
        Boundary(name: "top", shape: Box(min: (-0.0015, 0.005, 0.0), max: (0.026, 0.0065, 0.0))),
        Boundary(name: "back", shape: Box(min: (-0.0015, 0.0, 0.0), max: (0.0, 0.005, 0.0))),
    ],
    fixed_regions: [ Box(min: (-1.0, -1.0, -1.0), max: (0.02, 1.0, 1.0)) ],
    outlets: [ Outlet(name: "out", region: Box(min: (0.02, 0.0, 0.0), max: (0.026, 0.005, 0.0)),
        pressure: 0.0, normal: (1.0, 0.0, 0.0)) ],
    sinks: [ Sink(name: "sink", region: Box(min: (0.026, -0.002, 0.0), max: (0.03, 0.007, 0.0))) ],
    duration: 0.5,
)"#;
    Scenario::from_str_named(text, "porous channel (test)").expect("scenario")
}

/// Continuity across an outlet's face (README: "Pressure outlets"): the buffer is pure liquid at the
/// outlet's density ρ_o, so it must carry off the mass flux ρ_j v_j of the liquid that reaches it, not its
/// velocity v_j — for liquid leaving a porous skeleton at nˡ = 0.4 the two differ by 2.5×. Reference:
/// mass conservation — drained at a steady rate, the buffer stays full, its liquid volume Σ m/ρ₀ over
/// its area ρ_o/ρ₀ = 1 (0 Pa gauge). Measured (CPU, 0.05-s samples to 0.5 s, ≈ 180 of 520 particles
/// sunk, the buffer's 120 replaced 1.5 times): 0.97 falling to a steady 0.71–0.73; a buffer moving at
/// v_j falls to 0.25–0.36. The rest of the deficit is the kernel at the face: the open liquid nearest
/// the buffer counts the buffer's pure liquid in its ρ_j, so its flux reads high. (Probes, 2026-12-05:
/// the same mass flux sampled on a plane R_l–2R_l in front of the face keeps the buffer 0.91–1.0 full
/// and drains 102–108 particles instead of 180 — but in a converging sink such as the syringe's needle
/// tip that plane sees a lower flux density than the face, so it is not the rule; capping ρ_j/ρ_o at
/// 1 − nˢ_j changed nothing here and broke the sealed column.) Asserted: at least 0.65 full at every
/// sample, and at most 1.1 (no pile-up).
#[test]
fn an_outlet_buffer_drained_from_a_porous_skeleton_stays_full() {
    let sc = porous_channel_into_an_outlet();
    let mut sim = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
    let o = sim.params().outlets[0];
    let area = f64::from((o.max.x - o.min.x) * (o.max.y - o.min.y));
    let n0 = sim.read_state().expect("state").liquid.len();
    let mut fills = Vec::new();
    for k in 1..=10 {
        sim.advance_until(0.05 * k as f64, u64::MAX, |_| {}).expect("run");
        let st = sim.read_state().expect("state");
        let v: f64 = (0..st.liquid.len())
            .filter(|&i| o.contains(st.liquid.pos[i]))
            .map(|i| f64::from(st.liquid.mass[i]) / 1000.0)
            .sum();
        fills.push(v / area);
    }
    let sunk = sim.emit_totals().expect("totals").sunk;
    eprintln!("the buffer's liquid volume over its area at 0.05 … 0.5 s: {fills:.3?}; {sunk} of {n0} particles sunk");
    assert!(sunk >= 150, "the channel drained only {sunk} particles");
    for (k, f) in fills.iter().enumerate() {
        assert!((0.65..=1.1).contains(f), "t = {:.2} s: the buffer is {f:.3} full", 0.05 * (k + 1) as f64);
    }
}
