//! Coulomb friction of solid tissue on boundary objects (README: deviations from SPEC — SPEC §4.1's
//! contact is frictionless), checked against the textbook sliding block: a block launched at v₀ on a
//! level plate decelerates at μg and stops after v₀²/(2μg); on a plane tilted by θ it stays put when
//! tan θ < μ and slides at g(sin θ − μ cos θ) when tan θ > μ. CPU back-end; the GPU twin is held to
//! the CPU by `gpu_vs_cpu::wall_friction_matches_cpu`.

mod common;

use common::scenes::sliding_block;
use perfuse::sim::{BackendKind, Simulation};

const G: f64 = 9.81;

/// (t, centroid x, centroid v_x, centroid z) of the block every `every` seconds up to `t_end`.
fn trajectory(mu: Option<f64>, v0: f64, tilt: f64, t_end: f64, every: f64) -> Vec<(f64, f64, f64, f64)> {
    let gravity = [G * tilt.sin(), 0.0, -G * tilt.cos()];
    let mut sim = Simulation::new(&sliding_block(mu, v0, gravity), BackendKind::Cpu).expect("sliding block");
    let mut out = Vec::new();
    let mut t = 0.0;
    loop {
        let s = sim.read_state().expect("state");
        let n = s.solid.len() as f64;
        let x = s.solid.pos.iter().map(|p| p.x as f64).sum::<f64>() / n;
        let z = s.solid.pos.iter().map(|p| p.z as f64).sum::<f64>() / n;
        let vx = s.solid.vel.iter().map(|v| v.x as f64).sum::<f64>() / n;
        out.push((s.t, x, vx, z));
        if t >= t_end - 1e-12 {
            return out;
        }
        t += every;
        sim.advance_until(t, 1_000_000, |_| {}).expect("the block slides without diverging");
    }
}

/// Least-squares slope of y over x.
fn slope(pts: &[(f64, f64)]) -> f64 {
    let n = pts.len() as f64;
    let (mx, my) = (pts.iter().map(|p| p.0).sum::<f64>() / n, pts.iter().map(|p| p.1).sum::<f64>() / n);
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    sxy / sxx
}

/// A block launched at 0.3 m/s on a level plate with μ = 0.5 decelerates at μg = 4.905 m/s² (±10 %)
/// and stops after v₀²/(2μg) = 9.17 mm (±15 %: the launched block's contact load takes a few ms to
/// build); on a frictionless plate (μ = 0) it keeps its speed.
#[test]
fn kinetic_friction_stops_a_sliding_block_at_mu_g() {
    let (mu, v0) = (0.5, 0.3);
    let tr = trajectory(Some(mu), v0, 0.0, 0.1, 0.0025);
    let sliding: Vec<(f64, f64)> = tr.iter().filter(|p| p.2 < 0.8 * v0 && p.2 > 0.2 * v0).map(|p| (p.0, p.2)).collect();
    assert!(sliding.len() >= 5, "the block must decelerate through 0.8–0.2 v₀ over several samples: {tr:?}");
    let a = slope(&sliding);
    let travel = tr.last().expect("samples").1 - tr[0].1;
    let v_end = tr.last().expect("samples").2;
    let (a_ref, d_ref) = (-mu * G, v0 * v0 / (2.0 * mu * G));
    eprintln!(
        "μ = {mu}: deceleration {a:.3} m/s² (μg = {:.3}), travel {:.2} mm (v₀²/2μg = {:.2} mm), v(0.1 s) = {v_end:.4} m/s",
        -a_ref,
        travel * 1e3,
        d_ref * 1e3
    );
    assert!((a - a_ref).abs() <= 0.1 * a_ref.abs(), "deceleration {a:.3} vs −μg {a_ref:.3}");
    assert!((travel - d_ref).abs() <= 0.15 * d_ref, "travel {travel:.5} m vs v₀²/(2μg) {d_ref:.5} m");
    assert!(v_end.abs() < 0.02 * v0, "the block has stopped: v = {v_end} m/s");
    // Controls: with μ = 0 the block keeps its speed; SPEC §4.1's contact (friction: None), whose
    // artificial viscosity sees the whole relative velocity, drags it to a stop — a numerical friction
    // that depends on speed, sound speed and resolution, the reason Coulomb contact exists.
    let free = trajectory(Some(0.0), v0, 0.0, 0.06, 0.06);
    let v_free = free.last().expect("samples").2;
    let spec = trajectory(None, v0, 0.0, 0.06, 0.06);
    let v_spec = spec.last().expect("samples").2;
    eprintln!("v(0.06 s): μ = 0 {v_free:.4} m/s; SPEC §4.1 contact {v_spec:.4} m/s");
    assert!(v_free > 0.98 * v0, "a frictionless plate keeps the block sliding: {v_free} m/s");
}

/// On a plane tilted by θ: with tan θ = 0.2 < μ = 0.4 the block stays (centroid moves < 0.5 mm in
/// 0.1 s, where frictionless sliding would cover ½g sin θ t² = 9.6 mm); with tan θ = 0.8 > μ it slides
/// at g(sin θ − μ cos θ) = 3.06 m/s² (±10 %).
#[test]
fn inclined_block_sticks_below_and_slides_above_the_friction_angle() {
    let mu = 0.4;
    let stick = trajectory(Some(mu), 0.0, 0.2f64.atan(), 0.1, 0.1);
    let creep = stick.last().expect("samples").1 - stick[0].1;
    eprintln!("tan θ = 0.2, μ = {mu}: the centroid moved {:.3} mm in 0.1 s", creep * 1e3);
    assert!(creep.abs() < 5e-4, "below the friction angle the block stays: moved {creep} m");
    let theta = 0.8f64.atan();
    let tr = trajectory(Some(mu), 0.0, theta, 0.1, 0.005);
    let late: Vec<(f64, f64)> = tr.iter().filter(|p| p.0 >= 0.02).map(|p| (p.0, p.2)).collect();
    let a = slope(&late);
    let a_ref = G * (theta.sin() - mu * theta.cos());
    eprintln!("tan θ = 0.8, μ = {mu}: acceleration {a:.3} m/s² (g(sin θ − μ cos θ) = {a_ref:.3})");
    assert!((a - a_ref).abs() <= 0.1 * a_ref, "sliding acceleration {a:.3} vs {a_ref:.3}");
}

/// μ outside [0, 2] or not a number is refused with the field's name.
#[test]
fn absurd_friction_is_refused() {
    for bad in ["-0.1", "3.0", "NaN"] {
        let sc = perfuse::scenario::Scenario::from_str_named(
            &format!(
                r#"Scenario(name: "b", dimensions: 2, domain: Domain(min: (0.0, 0.0, 0.0), max: (0.01, 0.01, 0.0)),
                solid: Some(Solid(density: 1000.0, c10: 1e3, c01: 0.0, k_s: 1e4, n_sat: 1.0, k_sat: 0.0)),
                numerics: Numerics(dx_solid: Some(0.001)),
                particles: [ Box(phase: Solid, min: (0.002, 0.002, 0.0), max: (0.008, 0.008, 0.0), fraction: 1.0) ],
                boundaries: [ Boundary(name: "floor", shape: Box(min: (0.0, 0.0, 0.0), max: (0.01, 0.002, 0.0)),
                                       friction: Some({bad})) ],
                duration: 0.01)"#
            ),
            "bad_friction.ron",
        );
        let err = sc.expect_err(&format!("friction {bad} must be refused")).to_string();
        assert!(err.contains("boundaries[0].friction"), "the message names the field: {err}");
    }
}
