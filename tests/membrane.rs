//! Glisson's capsule (thesis §3.1.2–3.1.3, SPEC §4.5): detection of the outer layer by the offset of the
//! neighbourhood centre of mass, resolution enhancement (three children per membrane particle, parent
//! mass shared), and an intact capsule holding its blood (issue: surgical tissue, first increment).

use perfuse::analysis::capsule;
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
    capsule::write_cube_mesh(&dir, a, b).expect("write mesh");
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

/// The hanging cube of `analysis::capsule` (n³ sites at 5 mm) with its mesh in a fresh temporary
/// directory, which the caller removes.
fn hanging_perfused_cube(tag: &str, n: usize) -> (Scenario, std::path::PathBuf) {
    let dir = std::env::temp_dir().join(format!("perfuse-capsule-{tag}-{}", std::process::id()));
    let sc = capsule::hanging_cube(&dir, n, 0.005).unwrap_or_else(|e| panic!("{e}"));
    (sc, dir)
}

/// The capsule continues the tissue for the blood beneath it (its ghost sites, `sim::ghosts`; README:
/// deviations from SPEC): at rest, liquid beneath a face sees the tissue's nˢ and a saturated mixture,
/// as in the bulk, on both back-ends (2026-12-06 with the capsule's layers, which the ghosts replaced:
/// nˢ 0.702, nˡ 0.298 beneath the faces; 0.707, 0.300 in the bulk). With the membrane alone it saw half a
/// kernel of tissue (nˢ ≈ 0.4, nˡ 0.34) and a penalty pressure (2.53) of 0 however much blood collected
/// there, so the capsule held blood only by the hydrostatic part of its mirror pressure and the default
/// liver lost blood through its lower face.
#[test]
fn the_capsule_continues_the_tissue_for_the_blood_beneath_it() {
    let (sc, dir) = hanging_perfused_cube("fractions", 10);
    let dx = 0.005f32;
    for backend in [BackendKind::Cpu, BackendKind::Gpu] {
        let mut sim = Simulation::new(&sc, backend).expect("sim");
        sim.step().expect("step");
        let s = sim.read_state().expect("state");
        // beneath the centre of each face: the outermost liquid plane, half a spacing inside the
        // capsule's, ≥ 2Δx from the edges (state positions are relative to the scene's origin: the
        // lattice's site 1Δx is the liquid's smallest coordinate)
        let o = s.liquid.pos.iter().fold(glam::Vec3::INFINITY, |m, x| m.min(*x)) - glam::Vec3::splat(dx);
        let (lo, hi) = (1.0 * dx, 9.0 * dx);
        let (mut face, mut bulk) = (Vec::new(), Vec::new());
        for (i, x) in s.liquid.pos.iter().enumerate() {
            let x = *x - o;
            let c = [x.x, x.y, x.z];
            let on_face = c.iter().filter(|&&v| (v - lo).abs() < 0.3 * dx || (v - hi).abs() < 0.3 * dx).count();
            let inner = c.iter().all(|&v| v > 2.5 * dx && v < 7.5 * dx);
            let centred = c.iter().filter(|&&v| v > 2.5 * dx && v < 7.5 * dx).count() == 2;
            if on_face == 1 && centred {
                face.push(i);
            } else if inner {
                bulk.push(i);
            }
        }
        let mean = |set: &[usize], v: &[f32]| set.iter().map(|&i| v[i]).sum::<f32>() / set.len() as f32;
        let (ns_face, ns_bulk) = (mean(&face, &s.liquid.n_s), mean(&bulk, &s.liquid.n_s));
        let (nl_face, nl_bulk) = (mean(&face, &s.liquid.n_l), mean(&bulk, &s.liquid.n_l));
        println!(
            "{:?}: {} liquid beneath the faces: nˢ {ns_face:.3}, nˡ {nl_face:.3}; {} in the bulk: nˢ {ns_bulk:.3}, nˡ {nl_bulk:.3}",
            backend,
            face.len(),
            bulk.len()
        );
        assert_eq!(face.len(), 6 * 25, "the test's selection of the liquid beneath the faces");
        assert!((ns_bulk - 0.7).abs() < 0.02, "bulk nˢ {ns_bulk}");
        assert!(
            (ns_face - ns_bulk).abs() < 0.02 * ns_bulk,
            "beneath the capsule nˢ = {ns_face}, in the bulk {ns_bulk}"
        );
        assert!(
            (ns_face + nl_face - 1.0).abs() < 0.02,
            "beneath the capsule the mixture is not saturated: nˢ + nˡ = {}",
            ns_face + nl_face
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Blood in a perfused 8³ cube that hangs from its top plane drains at the Darcy speed (≈ 1 cm/s) onto
/// the capsule, which holds it (SPEC §4.5 and issue 6 §1: no liquid outside the intact capsule): after
/// 0.12 s (2 216 steps; the blood has sunk ≈ 1.2 mm) no liquid particle lies beyond the capsule's local
/// hull, none has left the tissue, the lowest blood lies above the capsule's lowest particle and no bond
/// broke. Both back-ends. With the thesis's single-layer capsule (no seal, no ghost sites or layers
/// beneath it) 5 particles lay beyond it by then and the lowest blood 0.5 mm below the capsule
/// (2026-12-06), through its lower face and the lower part of its sides, as the default liver's blood
/// left through its lower face.
#[test]
fn a_hanging_perfused_cube_keeps_its_blood_in_its_capsule() {
    let (sc, dir) = hanging_perfused_cube("hanging", 8);
    let g = perfuse::scenario::generate(&sc);
    for backend in [BackendKind::Cpu, BackendKind::Gpu] {
        let mut sim = Simulation::from_generated(&sc, g.clone(), backend).expect("sim");
        sim.advance_until(0.12, u64::MAX, |_| {}).expect("runs");
        let s = sim.read_state().expect("state");
        let beyond = capsule::liquid_beyond_capsule(&s, &g.solid_normal, 0.005);
        let lowest_liquid = s.liquid.pos.iter().map(|x| x.y).fold(f32::INFINITY, f32::min);
        let lowest_solid = s.solid.pos.iter().map(|x| x.y).fold(f32::INFINITY, f32::min);
        let p_bottom = s
            .liquid
            .pos
            .iter()
            .zip(&s.liquid.p)
            .filter(|(x, _)| x.y < lowest_solid + 0.0075)
            .map(|(_, p)| *p)
            .sum::<f32>()
            / s.liquid.pos.iter().filter(|x| x.y < lowest_solid + 0.0075).count().max(1) as f32;
        println!(
            "{:?}: {} steps to t = {:.3} s; liquid beyond the capsule {beyond}, outside {}; lowest liquid {:.2} mm, \
             lowest solid {:.2} mm; mean pressure of the lowest blood {p_bottom:.0} Pa; broken bonds {}",
            backend,
            s.steps,
            s.t,
            s.liquid_outside(),
            lowest_liquid * 1e3,
            lowest_solid * 1e3,
            s.broken_bonds()
        );
        assert_eq!(beyond, 0, "{beyond} liquid particles beyond the intact capsule");
        assert_eq!(s.liquid_outside(), 0);
        assert_eq!(s.broken_bonds(), 0);
        assert!(lowest_liquid > lowest_solid, "blood below the capsule's lowest particle");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The capsule's ghost sites (`membrane.ghosts`, `sim::ghosts`; README: deviations from SPEC) give the
/// blood at the capsule the generated fractions at faces, edges and corners alike, on both back-ends:
/// the CI specimen (12³ tissue / 11³ blood lattices, which do not coincide) after one step, its blood
/// grouped by how many of the cube's faces lie within 5 mm. With ghosts every group's mean nˢ is the
/// tissue's 0.6 and nˡ the blood's 0.4 within 0.01 (2026-12-07: nˢ 0.597–0.603, nˡ 0.400 in every
/// group; 0.391 at the edges while the ghosts were counted only beneath the particles' plane). With
/// the capsule's layers, which the ghosts replaced in session 56, the edges and corners saw a third to a
/// half less tissue (nˢ 0.414 at the edges, 0.287 at the corners) and the faces more blood (nˡ 0.482);
/// without either (`membrane.ghosts = false`, the thesis's capsule) the blood sees nˢ 0.453 at the faces,
/// 0.340 at the edges, 0.252 at the corners (nˡ 0.517, 0.459, 0.385).
#[test]
fn ghost_sites_give_the_blood_the_generated_fractions_everywhere() {
    let mut bare = [0.0f32; 4];
    for ghosts in [true, false] {
        let mut sc = specimen_ci();
        if let Some(m) = sc.membrane.as_mut() {
            m.ghosts = ghosts;
        }
        let backends: &[BackendKind] = if ghosts { &[BackendKind::Cpu, BackendKind::Gpu] } else { &[BackendKind::Cpu] };
        for &backend in backends {
            let mut sim = Simulation::new(&sc, backend).expect("sim");
            sim.step().expect("step");
            let s = sim.read_state().expect("state");
            let lo = s.solid.pos.iter().fold(glam::Vec3::INFINITY, |m, x| m.min(*x));
            let hi = s.solid.pos.iter().fold(glam::Vec3::NEG_INFINITY, |m, x| m.max(*x));
            // per group (0 faces near: bulk, 1: faces, 2: edges, 3: corners): Σ nˢ, Σ nˡ, count
            let mut g = [[0.0f32; 3]; 4];
            for (i, x) in s.liquid.pos.iter().enumerate() {
                let near = (0..3).filter(|&a| x[a] - lo[a] < 0.005 || hi[a] - x[a] < 0.005).count();
                g[near] = [g[near][0] + s.liquid.n_s[i], g[near][1] + s.liquid.n_l[i], g[near][2] + 1.0];
            }
            let names = ["bulk", "faces", "edges", "corners"];
            for (k, [ns, nl, n]) in g.iter().enumerate() {
                let (ns, nl) = (ns / n, nl / n);
                println!("ghosts {ghosts}, {backend:?}: {} {n} liquid: nˢ {ns:.3}, nˡ {nl:.3}", names[k]);
                assert!(*n > 0.0, "no liquid at the {}", names[k]);
                if ghosts {
                    assert!((ns - 0.6).abs() < 0.01 && (nl - 0.4).abs() < 0.01, "{}: nˢ {ns}, nˡ {nl}", names[k]);
                } else {
                    bare[k] = ns;
                }
            }
        }
    }
    assert!(bare[1] < 0.5 && bare[2] < 0.5 && bare[3] < 0.4, "the bare capsule's faces, edges, corners: nˢ {bare:?}");
}
