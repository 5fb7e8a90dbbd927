//! `perfuse dmd` from the command line: the frames of a run in, `dmd.json` and the plots out, with the
//! amplitude fit chosen by `--amplitudes` (thesis §5.2's initial value problem, or the optimal amplitudes
//! over the whole record), and a clear refusal of a value it does not know.

use std::path::{Path, PathBuf};
use std::process::Command;

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("perfuse-dmd-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

/// Eight liquid particles sloshing at 0.5 Hz with a phase along the tank, plus a slowly decaying
/// transient (so the record is not exactly one oscillation), 2-D, frames every 0.01 s for 4 s.
fn write_sloshing_frames(dir: &Path) {
    let header = "phase,id,x,y,z,vx,vy,vz,density,n_s,n_l,pressure";
    for k in 0..=400usize {
        let t = k as f64 * 0.01;
        let w = 2.0 * std::f64::consts::PI * 0.5;
        let mut text = format!("{header}\n");
        for id in 0..8u64 {
            let x0 = id as f64 / 8.0;
            let x = x0 + 0.04 * (w * t + 3.0 * x0).sin() + 0.01 * (-t).exp() * x0;
            let y = 0.3 + 0.02 * x0 * (w * t + 3.0 * x0).cos();
            text.push_str(&format!("liquid,{id},{x:.9e},{y:.9e},0,0,0,0,1000,0,1,0\n"));
        }
        std::fs::write(dir.join(format!("frame_{k:05}.csv")), text).expect("write frame");
    }
}

fn dmd(frames: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_perfuse"))
        .arg("dmd")
        .arg(frames)
        .args(["--frame-interval", "0.01", "--rank", "8", "--out"])
        .arg(out)
        .args(extra)
        .output()
        .expect("run perfuse")
}

fn report(out: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(out.join("dmd.json")).expect("dmd.json");
    serde_json::from_str(&text).expect("dmd.json is JSON")
}

#[test]
fn amplitudes_flag_selects_the_fit_and_the_optimal_one_is_no_worse() {
    let dir = temp_dir("amplitudes");
    let frames = dir.join("frames");
    std::fs::create_dir_all(&frames).expect("frames dir");
    write_sloshing_frames(&frames);

    let mut errors = Vec::new();
    for (flag, fit) in [(None, "initial condition x_1"), (Some("all"), "all snapshots (optimal amplitudes)")] {
        let out = dir.join(flag.unwrap_or("default"));
        let extra: Vec<&str> = flag.map(|f| vec!["--amplitudes", f]).unwrap_or_default();
        let o = dmd(&frames, &out, &extra);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let r = report(&out);
        assert_eq!(r["amplitude_fit"], fit, "{flag:?}");
        assert_eq!(r["rank"], 8);
        let f = r["dominant_frequency_hz"].as_f64().expect("an oscillating mode");
        assert!((f - 0.5).abs() < 0.005, "dominant {f} Hz with {flag:?}");
        assert!(out.join("position_error.png").is_file());
        errors.push(r["reconstruction_error"].as_f64().expect("error"));
    }
    // The optimal amplitudes minimise the record's squared error, so the mean relative error cannot be
    // much larger than with the amplitudes of the first snapshot.
    assert!(errors[1] <= errors[0] * 1.05 + 1e-9, "optimal {} vs initial {}", errors[1], errors[0]);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn an_unknown_amplitude_fit_is_refused_with_the_choices() {
    let dir = temp_dir("bad");
    let o = dmd(&dir, &dir.join("out"), &["--amplitudes", "best"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--amplitudes") && err.contains("initial") && err.contains("all"), "{err}");
    assert!(!dir.join("out").exists(), "nothing written");
    let _ = std::fs::remove_dir_all(&dir);
}
