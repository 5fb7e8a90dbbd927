//! Glisson's capsule (thesis §3.1.2–3.1.3, SPEC §4.5): detection of the outer layer by the offset of the
//! neighbourhood centre of mass, resolution enhancement (three children per membrane particle, parent
//! mass shared), and an intact capsule holding its blood (issue: surgical tissue, first increment).

use perfuse::scenario::{Scenario, SolidFlags};
use perfuse::sim::{BackendKind, Simulation};
use std::path::Path;

/// The shipped specimen at the CI resolution of SPEC §7.5 (12³ solid / 11³ liquid), no relaxation.
fn specimen_ci() -> Scenario {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/specimen.ron");
    let dx_s = 0.05 / 12.0;
    let set = [
        "relaxation=null".to_string(),
        format!("numerics.dx_solid={dx_s}"),
        format!("numerics.dx_liquid={}", 0.05 / 11.0),
        format!("numerics.h_liquid={}", 1.3 * dx_s),
        format!("boundaries.0.spacing={dx_s}"),
        format!("boundaries.0.shape.min=[-0.075, -0.075, {}]", -3.0 * dx_s),
    ];
    Scenario::load_with_overrides(&path, &set).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn detection_finds_the_outer_layer_and_enhancement_quadruples_it() {
    let sc = specimen_ci();
    let g = perfuse::scenario::generate(&sc);
    let lattice = 12usize.pow(3);
    // Outer layer 12³ − 10³ = 728 plus the particle diagonally inside each of the 8 corners (|d| = 0.577Δx).
    let parents = 728 + 8;
    assert_eq!(g.solid.pos.len(), lattice + 3 * parents);
    let membrane = g.solid_flags.iter().filter(|f| *f & SolidFlags::MEMBRANE != 0).count();
    assert_eq!(membrane, 4 * parents);
    // Total solid mass is unchanged by the enhancement.
    let total: f64 = g.solid.mass.iter().sum();
    assert!((total - lattice as f64 * g.mass_solid).abs() < 1e-9 * total, "{total}");
    // Membrane particles show the liquid a quarter of a lattice site's equivalent mass each.
    let m_bl: Vec<f64> = g.solid_liquid_boundary_mass.iter().copied().filter(|m| *m > 0.0).collect();
    assert_eq!(m_bl.len(), membrane);
}

#[test]
fn intact_capsule_holds_its_blood() {
    let sc = specimen_ci();
    let mut sim = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
    for _ in 0..300 {
        sim.step().expect("step");
    }
    let s = sim.read_state().expect("state");
    let outside = s.liquid.n_s.iter().filter(|&&n| n < 0.05).count();
    assert_eq!(outside, 0, "{outside} liquid particles left the capsule");
    // Not asserted yet (issue: surgical tissue): without relaxation the enhanced surface is far from
    // equilibrium and ~5 400 bonds born within 2 % of the search radius break under the thesis criterion.
}
