//! Elastic ligament attachments (`Scenario::ligaments`, README: deviations from SPEC): each tethered
//! solid particle feels a = −ω²(x − X) − 2ζω v toward its anchor X. A block tethered everywhere and
//! loaded by gravity translates as a rigid body (uniform load, no strain, so no tissue stress), and its
//! displacement must follow the damped oscillator's closed form
//!   u(t) = δ[1 − e^{−ζωt}(cos ω_d t + ζω/ω_d sin ω_d t)],  δ = g/ω², ω_d = ω√(1 − ζ²)
//! (ζ = 1: u = δ[1 − (1 + ωt)e^{−ωt}]). The GPU twin is in `gpu_vs_cpu::tethered_block_matches_cpu`.

use perfuse::scenario::{Scenario, SolidFlags, generate};
use perfuse::sim::cpu::CpuSolver;
use perfuse::sim::params::Params;

const G: f64 = 9.81;

/// A dry 3-D block of 5³ solid particles at Δx = 1 mm under gravity −z, tethered everywhere (or only
/// where `region` says) at `frequency` Hz with damping ratio `zeta`.
fn tethered_block(frequency: f64, zeta: f64, region: &str) -> Scenario {
    let text = format!(
        r#"Scenario(
        name: "tethered_block", dimensions: 3,
        domain: Domain(min: (-0.01, -0.01, -0.01), max: (0.01, 0.01, 0.01)),
        gravity: (0.0, 0.0, -{G}),
        solid: Some(Solid(density: 1000.0, c10: 1e4, c01: 100.0, k_s: 1e4, n_sat: 1.0, k_sat: 0.0)),
        numerics: Numerics(dx_solid: Some(0.001)),
        particles: [ Box(phase: Solid, min: (-0.0025, -0.0025, -0.0025), max: (0.0025, 0.0025, 0.0025), fraction: 1.0) ],
        ligaments: Some(Ligaments(regions: [{region}], frequency: {frequency:?}, damping_ratio: {zeta:?})),
        duration: 0.1,
    )"#
    );
    Scenario::from_str_named(&text, "tethered_block.ron").expect("test scene is valid")
}

const EVERYWHERE: &str = "Box(min: (-1.0, -1.0, -1.0), max: (1.0, 1.0, 1.0))";

/// Closed-form displacement (downward positive) of a damped oscillator released at rest under g.
fn oscillator(t: f64, omega: f64, zeta: f64) -> f64 {
    let delta = G / (omega * omega);
    if zeta < 1.0 {
        let wd = omega * (1.0 - zeta * zeta).sqrt();
        delta * (1.0 - (-zeta * omega * t).exp() * ((wd * t).cos() + zeta * omega / wd * (wd * t).sin()))
    } else {
        delta * (1.0 - (1.0 + omega * t) * (-omega * t).exp())
    }
}

/// Runs the block to `until`, comparing the mean and the spread of the particles' downward
/// displacement with the closed form at every step. Returns (max |ū − u|, max spread) over δ.
fn follow(sc: &Scenario, until: f64) -> (f64, f64, usize) {
    let g = generate(sc);
    let mut cpu = CpuSolver::new(Params::new(sc, &g), &g).expect("CPU solver");
    let lig = sc.ligaments.as_ref().expect("ligaments");
    let omega = 2.0 * std::f64::consts::PI * lig.frequency;
    let delta = G / (omega * omega);
    let z0: Vec<f64> = cpu.st.solid.x.iter().map(|x| x.z as f64).collect();
    let (mut err, mut spread, mut steps) = (0.0f64, 0.0f64, 0);
    while cpu.st.t < until {
        cpu.step().expect("step");
        steps += 1;
        let u: Vec<f64> = cpu.st.solid.x.iter().zip(&z0).map(|(x, z)| z - x.z as f64).collect();
        let mean = u.iter().sum::<f64>() / u.len() as f64;
        let (lo, hi) = u.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
        err = err.max((mean - oscillator(cpu.st.t, omega, lig.damping_ratio)).abs() / delta);
        spread = spread.max((hi - lo) / delta);
    }
    (err, spread, steps)
}

#[test]
fn every_particle_of_a_ligament_region_is_tethered_and_none_kinematic() {
    let sc = tethered_block(20.0, 1.0, "Sphere(centre: (0.0, 0.0, 0.0025), radius: 0.0012)");
    let g = generate(&sc);
    let tethered = g.solid_flags.iter().filter(|&&f| f & SolidFlags::TETHERED != 0).count();
    assert!(g.solid_flags.iter().all(|f| f & SolidFlags::KINEMATIC == 0), "no kinematic particle");
    // the lattice sites at z = 2 mm: the top face's centre (0.5 mm from the ball's centre) and its 4
    // neighbours (1.12 mm); the diagonal ones and the one below lie 1.5 mm away
    assert_eq!(tethered, 5, "tethered particles in a 1.2-mm ball over the top face's centre");
    let params = Params::new(&sc, &g);
    let omega = 2.0 * std::f32::consts::PI * 20.0;
    assert!((params.tether_omega2 - omega * omega).abs() <= 1e-3 * omega * omega);
    assert!((params.tether_damping - 2.0 * omega).abs() <= 1e-5 * omega);
}

/// Runs [`follow`] and holds the block to the closed form and to rigid translation within 10⁻³ δ.
fn assert_follows_the_oscillator(label: &str, sc: &Scenario, until: f64) {
    let (err, spread, steps) = follow(sc, until);
    eprintln!("{label}: max |ū − u| = {err:.2e} δ, spread {spread:.2e} δ over {steps} steps");
    assert!(err <= 1e-3, "{label}: mean displacement off the closed form by {err} δ");
    assert!(spread <= 1e-3, "{label}: the block deformed: spread {spread} δ");
}

/// Undamped: the block swings about δ = g/ω² with the springs' period (20 Hz, 1.5 periods).
#[test]
fn an_undamped_tethered_block_oscillates_at_the_spring_frequency() {
    assert_follows_the_oscillator("undamped", &tethered_block(20.0, 0.0, EVERYWHERE), 0.075);
}

/// Critically damped: the block settles onto δ = g/ω² without overshoot (ζ = 1, 40 Hz, 0.06 s ≈ 15/ω).
#[test]
fn a_critically_damped_tethered_block_settles_at_g_over_omega_squared() {
    assert_follows_the_oscillator("critical", &tethered_block(40.0, 1.0, EVERYWHERE), 0.06);
}
