//! The patient of a headless run (issue 7 §3–4, `physiology`): liquid outside the solid body is lost
//! from the circulation × volume_scale, the vitals are sampled per frame into vitals.csv, and
//! summary.json carries blood_lost_ml, model_hepatic_volume_m3 and vitals_final. Without a wound (all
//! blood inside the tissue) nothing is lost.

use perfuse::output::{RunLength, RunOptions, run_headless};
use perfuse::scenario::Scenario;
use perfuse::sim::BackendKind;

/// A tissue block (perfused) beside a free ball of blood (outside the body: nˢ = 0 there).
fn scene(with_ball: bool) -> Scenario {
    let ball = if with_ball {
        "Sphere(phase: Liquid, centre: (0.009, 0.003, 0.0035), radius: 0.0015, fraction: 0.4),"
    } else {
        ""
    };
    let text = format!(
        r#"Scenario(
    name: "patient", dimensions: 3,
    domain: Domain(min: (0.0, 0.0, 0.0), max: (0.012, 0.006, 0.007)),
    liquid: Some(Liquid(density: 1000.0, viscosity: 0.01, sound_speed: Some(2.0))),
    solid: Some(Solid(density: 1000.0, c10: 1000.0, c01: 100.0, k_s: 10000.0, n_sat: 0.6, k_sat: 1000.0, friction: 10000.0)),
    numerics: Numerics(dx_liquid: Some(5.0e-4), dx_solid: Some(5.0e-4), h_over_dx: 1.3),
    particles: [
        PerfusedBlock(min: (0.001, 0.001, 0.0015), max: (0.005, 0.005, 0.004), solid_fraction: 0.6, liquid_fraction: 0.4),
        {ball}
    ],
    duration: 0.002,
    output: Output(frame_interval: Some(0.0005)),
    physiology: Some(Physiology(volume_scale: 1000.0)),
)"#
    );
    Scenario::from_str_named(&text, "patient.ron").expect("valid")
}

fn run(sc: &Scenario, name: &str) -> (perfuse::output::Summary, std::path::PathBuf) {
    let out = std::env::temp_dir().join(format!("perfuse-patient-{}-{name}", std::process::id()));
    let opts = RunOptions {
        backend: BackendKind::Cpu,
        length: Some(RunLength::Until(0.002)),
        out: Some(out.clone()),
        progress: false,
        vtk: false,
        relaxed_cache: None,
        fresh_relaxation: false,
    };
    (run_headless(sc, &opts).expect("run"), out)
}

#[test]
fn blood_outside_the_body_is_lost_by_the_patient() {
    let (s, out) = run(&scene(true), "ball");
    let gen_ = perfuse::scenario::generate(&scene(true));
    let block = perfuse::scenario::generate(&scene(false)).liquid.pos.len();
    let ball_n = gen_.liquid.pos.len() - block;
    let ball_m3: f64 = gen_.liquid.mass[block..].iter().sum::<f64>() / 1000.0;
    let lost = s.blood_lost_ml.expect("physiology on");
    eprintln!("ball {ball_n} particles = {:.3} mL simulated; patient lost {lost:.1} mL", ball_m3 * 1e6);
    // The ball (and possibly a few surface particles of the block) is outside: ×1000 in the patient.
    assert!(lost >= 0.99 * ball_m3 * 1e9 && lost <= 1.2 * ball_m3 * 1e9, "lost {lost} mL");
    let v = s.vitals_final.expect("vitals");
    assert!((v.blood_lost_ml - lost).abs() < 1e-9 && v.hr_bpm > 40.0 && v.map_mmhg > 40.0);
    assert!(s.model_hepatic_volume_m3.is_some_and(|q| q > 0.0), "hepatic inflow integrated");
    let csv = std::fs::read_to_string(out.join("vitals.csv")).expect("vitals.csv");
    assert!(csv.starts_with("t_s,hepatic_inflow_ml_s,map_mmhg"));
    assert!(csv.lines().count() >= 5, "one row per frame:\n{csv}");
    let json = std::fs::read_to_string(out.join("summary.json")).expect("summary");
    assert!(json.contains("\"blood_lost_ml\"") && json.contains("\"vitals_final\""));
    // The session's metrics (issue 7 §4) from the same samples: no cut in this scene; the 2 ms run is
    // shorter than the loss-rate window, so no rate yet.
    let m = s.session.as_ref().expect("session metrics with a patient");
    assert_eq!(m.blood_lost_ml, lost);
    assert_eq!((m.broken_bonds, m.first_cut_s, m.hemostasis_s), (s.broken_bonds, None, None));
    assert_eq!(m.peak_loss_rate_ml_min, 0.0);
    assert!(json.contains("\"session\"") && json.contains("\"peak_loss_rate_ml_min\""));
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn no_wound_no_loss() {
    let (s, out) = run(&scene(false), "intact");
    let outside = s.blood_outside_organ_m3.expect("physiology on");
    let total: f64 = perfuse::scenario::generate(&scene(false)).liquid.mass.iter().sum::<f64>() / 1000.0;
    eprintln!("intact block: {:.3e} of {:.3e} m³ outside", outside, total);
    assert!(outside < 0.02 * total, "blood inside perfused tissue is not lost: {outside} of {total} m³");
    let _ = std::fs::remove_dir_all(&out);
}

/// `perfuse vitals` refuses a bleeding time of zero (the loss is a rate over it, so nothing would be
/// lost) and a zero duration, naming the option, before writing anything.
#[test]
fn vitals_refuses_a_zero_bleeding_time_or_duration() {
    let out = std::env::temp_dir().join(format!("perfuse-vitals-args-{}", std::process::id()));
    for (args, named) in [(["--over", "0"], "--over 0"), (["--duration", "0"], "--duration 0")] {
        let r = std::process::Command::new(env!("CARGO_BIN_EXE_perfuse"))
            .arg("vitals")
            .args(args)
            .arg("--out")
            .arg(&out)
            .output()
            .expect("binary runs");
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success(), "{args:?} accepted");
        assert!(stderr.contains(named) && stderr.contains("seconds > 0"), "{stderr}");
        assert!(!stderr.contains("panicked") && !out.exists(), "{stderr}");
    }
}
