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

/// A perfused mesh's blood lies beneath its capsule (SPEC §4.5: the membrane is the liquid's virtual
/// boundary; README: deviations): a liquid particle in the membrane plane feels the membrane only
/// tangentially and is pushed out by the liquid behind it — the hanging liver lost blood through its flat
/// visceral face at rest that way. A cube mesh spanning [0.05, 10.25]Δx: the solid lattice (cell-centred)
/// has 10 sites per axis, its capsule the planes at 0.5Δx and 9.5Δx; the liquid lattice, half a spacing
/// from it, has sites at 1…10Δx inside the mesh, of which 1…9Δx lie beneath the capsule: 9³.
#[test]
fn perfused_mesh_liquid_starts_beneath_the_capsule() {
    let dx = 0.005;
    let (a, b) = (0.05 * dx, 10.25 * dx);
    let dir = std::env::temp_dir().join(format!("perfuse-capsule-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let v: Vec<String> =
        (0..8).map(|k| format!("v {} {} {}", [a, b][k & 1], [a, b][(k >> 1) & 1], [a, b][(k >> 2) & 1])).collect();
    // Quads of the cube (vertex k has x = bit 0, y = bit 1, z = bit 2), wound outward.
    let faces = "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
    std::fs::write(dir.join("cube.obj"), format!("{}\n{faces}", v.join("\n"))).expect("write mesh");
    let text = format!(
        r#"Scenario(
    name: "capsule_cube", dimensions: 3,
    domain: Domain(min: (-0.01, -0.01, -0.01), max: (0.07, 0.07, 0.07)),
    liquid: Some(Liquid(density: 1000.0, viscosity: 0.001, sound_speed: Some(10.0))),
    solid: Some(Solid(density: 1000.0, c10: 900.0, c01: 100.0, k_s: 2.0e4, n_sat: 0.7, k_sat: 2.0e4, friction: 1.0e6)),
    numerics: Numerics(dx_solid: Some({dx}), dx_liquid: Some({dx}), h_over_dx: 1.3, sound_speed_solid: Some(10.0)),
    particles: [PerfusedMesh(file: "cube.obj", solid_fraction: 0.7, liquid_fraction: 0.3)],
    membrane: Some(Membrane(threshold: 0.5, count: 3, radius: 0.5, angle: 0.7853981633974483)),
    duration: 0.1,
)"#
    );
    let sc = Scenario::from_str_named(&text, &dir.join("cube.ron").to_string_lossy()).unwrap_or_else(|e| panic!("{e}"));
    let g = perfuse::scenario::generate(&sc);
    assert_eq!(g.solid.pos.len(), 1000 + 3 * (1000 - 512 + 8), "10³ solid, capsule = outer layer + 8 corners");
    assert_eq!(g.liquid.pos.len(), 729, "the liquid sites between the capsule planes");
    let (lo, hi) = (0.5 * dx, 9.5 * dx);
    for p in &g.liquid.pos {
        assert!(
            p.iter().all(|&c| c >= lo + 0.45 * dx && c <= hi - 0.45 * dx),
            "liquid at {p:?} is not beneath the capsule"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A capsule child is fixed with its parent (SPEC §4.1/§4.5: a parent and its children are one lattice
/// site). A fixed region whose face lies a tenth of a spacing beyond a lattice plane holds that plane's
/// membrane parents; their children stick out of the region on both sides, and every one of them is
/// kinematic with its parent. (Before, the children outside the region were free: in the liver, one such
/// child on the rim of the ligament region was squeezed out during relaxation and broke 17 bonds.)
#[test]
fn capsule_children_are_fixed_with_their_parent() {
    let mut sc = specimen_ci();
    let dx = 0.05 / 12.0;
    let g0 = perfuse::scenario::generate(&sc);
    let lattice = 12usize.pow(3);
    let x_min = g0.solid.pos[..lattice].iter().map(|p| p[0]).fold(f64::INFINITY, f64::min);
    let face = x_min + 2.0 * dx + 0.1 * dx; // holds the first three lattice planes
    sc.fixed_regions = vec![perfuse::scenario::Region::Box { min: [-1.0, -1.0, -1.0], max: [face, 1.0, 1.0] }];
    let g = perfuse::scenario::generate(&sc);
    let kinematic = |i: usize| g.solid_flags[i] & SolidFlags::KINEMATIC != 0;
    let membrane = |i: usize| g.solid_flags[i] & SolidFlags::MEMBRANE != 0;
    let sites = (0..lattice).filter(|&i| kinematic(i)).count();
    let parents = (0..lattice).filter(|&i| kinematic(i) && membrane(i)).count();
    let fixed = (0..g.solid.pos.len()).filter(|&i| kinematic(i)).count();
    let outside = (lattice..g.solid.pos.len()).filter(|&i| kinematic(i) && g.solid.pos[i][0] > face).count();
    println!(
        "{sites} fixed sites ({parents} capsule parents), {fixed} fixed particles, {outside} children beyond the face"
    );
    assert_eq!(sites, 3 * 144, "three lattice planes of 12 × 12");
    assert_eq!(fixed, sites + 3 * parents, "each fixed capsule parent brings its three children");
    assert!(outside > 0, "the test needs children that stick out of the region");
    // and no free child sits at r_e = Δx/2 from a fixed parent in its tangent plane
    for i in lattice..g.solid.pos.len() {
        if !kinematic(i) {
            let p = g.solid.pos[i];
            assert!(p[0] > x_min + 2.0 * dx + 1e-9, "free child #{i} at x = {} inside the fixed planes", p[0]);
        }
    }
}

/// A stiffer capsule (`membrane.stiffness`, README: deviations): `solid_stress` gives a membrane
/// particle k times the Mooney–Rivlin τ of a tissue particle under the same deformation (τ is linear in
/// C10 and C01), and leaves the tissue's unchanged.
#[test]
fn a_stiffer_capsule_scales_the_membrane_stress_only() {
    use glam::Mat3;
    use perfuse::sim::cpu::{CpuSolver, solid};
    use perfuse::sim::params::Params;
    let k = 10.0f32;
    let mut sc = specimen_ci();
    sc.membrane.as_mut().expect("specimen has a capsule").stiffness = k as f64;
    let g = perfuse::scenario::generate(&sc);
    let mut cpu = CpuSolver::new(Params::new(&sc, &g), &g).expect("CPU solver");
    assert_eq!(cpu.params.membrane_stiffness, k);
    let f = Mat3::from_cols_array(&[1.05, 0.02, 0.0, 0.08, 0.97, 0.01, 0.0, -0.03, 1.02]);
    let s = &mut cpu.st.solid;
    s.def_grad.iter_mut().for_each(|d| *d = f);
    solid::solid_stress(&cpu.params, s);
    let plain = solid::mooney_rivlin_tau(f, cpu.params.c10, cpu.params.c01);
    let (mut n_mem, mut n_plain) = (0, 0);
    for (i, tau) in s.tau.iter().enumerate() {
        let membrane = s.flags[i] & SolidFlags::MEMBRANE != 0;
        let want = if membrane { plain * k } else { plain };
        let err = (*tau - want).abs().to_cols_array().into_iter().fold(0.0f32, f32::max);
        assert!(
            err <= 1e-5 * want.abs().to_cols_array().into_iter().fold(0.0f32, f32::max),
            "particle {i}: {tau} vs {want}"
        );
        if membrane { n_mem += 1 } else { n_plain += 1 }
    }
    assert!(n_mem > 0 && n_plain > 0, "{n_mem} membrane, {n_plain} plain");
}
