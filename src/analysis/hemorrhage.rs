//! A scripted hemorrhage through the closed-loop cardiovascular model alone (`sim::cardio`): blood
//! is removed at a constant rate, and the vitals are sampled into `vitals.csv` and plotted. It shows
//! what the model does when the organ bleeds (issue 7 §2–3, ATLS classes) before the SPH liver is
//! coupled to it; `perfuse vitals` runs it.

use super::plot::{Chart, Series, line_chart};
use crate::sim::cardio::{CardioError, CardioModel, CardioParams};
use std::path::Path;

pub use crate::output::VitalsSample;

/// Settles the heart, then removes `loss_fraction` of the blood volume uniformly over `over_s`
/// seconds starting at `start_s`, sampling every `sample_s` up to `duration_s`.
pub fn scripted_hemorrhage(
    params: CardioParams,
    loss_fraction: f64,
    start_s: f64,
    over_s: f64,
    duration_s: f64,
    sample_s: f64,
) -> Result<Vec<VitalsSample>, CardioError> {
    let mut m = CardioModel::settle(params)?;
    let t0 = m.time();
    let total_m3 = loss_fraction * m.circulating_volume_m3();
    let rate = if over_s > 0.0 { total_m3 / over_s } else { 0.0 };
    let mut out = Vec::new();
    let mut t = 0.0;
    while t <= duration_s + 1e-12 {
        let next = t + sample_s;
        m.advance_to(t0 + t);
        out.push(VitalsSample {
            t_s: t,
            hepatic_inflow_ml_s: m.hepatic_flow_m3_s() * 1e6,
            arterial_pressure_mmhg: m.arterial_pressure_mmhg(),
            vitals: m.vitals(),
            broken_bonds: 0,
        });
        // Remove the blood lost during [t, next) inside the bleeding window.
        let (a, b) = (t.max(start_s), next.min(start_s + over_s));
        if b > a {
            m.remove_volume(rate * (b - a));
        }
        t = next;
    }
    Ok(out)
}

/// Three-second windows of the pulse, sampled every 2 ms: (label, [(t within the window \[s\], hepatic
/// arterial inflow [mL/s], systemic arterial pressure \[mmHg\])]).
pub type PulseWindow = (String, Vec<(f64, f64, f64)>);

/// The pulse before the bleeding starts and at the end of the run of [`scripted_hemorrhage`] with the
/// same arguments: the 0.5 s samples alias the heartbeat, these resolve it (`hepatic_pulse.png`).
pub fn pulse_windows(
    params: CardioParams,
    loss_fraction: f64,
    start_s: f64,
    over_s: f64,
    duration_s: f64,
) -> Result<Vec<PulseWindow>, CardioError> {
    const DT: f64 = 2e-3;
    const SPAN: f64 = 3.0;
    let mut m = CardioModel::settle(params)?;
    let t0 = m.time();
    let total_m3 = loss_fraction * m.circulating_volume_m3();
    let rate = if over_s > 0.0 { total_m3 / over_s } else { 0.0 };
    let windows = [(start_s - SPAN).max(0.0), (duration_s - SPAN).max(0.0)];
    let mut out: Vec<PulseWindow> = Vec::new();
    let mut t = 0.0;
    for (k, &w0) in windows.iter().enumerate() {
        let mut pts = Vec::new();
        while t < w0 + SPAN - 1e-12 {
            let next = t + DT;
            m.advance_to(t0 + t);
            if t >= w0 {
                pts.push((t - w0, m.hepatic_flow_m3_s() * 1e6, m.arterial_pressure_mmhg()));
            }
            let (a, b) = (t.max(start_s), next.min(start_s + over_s));
            if b > a {
                m.remove_volume(rate * (b - a));
            }
            t = next;
        }
        let v = m.vitals();
        let label =
            if k == 0 { "baseline".to_string() } else { format!("{:.0} % lost", 100.0 * v.blood_lost_fraction) };
        out.push((format!("{label}, t = {w0:.0}–{:.0} s, HR {:.0} bpm", w0 + SPAN, v.hr_bpm), pts));
    }
    Ok(out)
}

/// `hepatic_pulse.png`: the pulsatile hepatic arterial inflow and the arterial pressure over three
/// seconds at baseline and at the end of the hemorrhage (time within each window).
pub fn write_pulse_plot(windows: &[PulseWindow], dir: &Path) -> Result<(), String> {
    let mut series = Vec::new();
    for (label, pts) in windows {
        series.push(Series {
            label: format!("inflow ×10 [mL/s], {label}"),
            points: pts.iter().map(|p| (p.0, 10.0 * p.1)).collect(),
            markers: false,
        });
        series.push(Series {
            label: format!("arterial pressure [mmHg], {label}"),
            points: pts.iter().map(|p| (p.0, p.2)).collect(),
            markers: false,
        });
    }
    line_chart(
        &dir.join("hepatic_pulse.png"),
        &Chart {
            title: "Pulse: hepatic arterial inflow and arterial pressure, baseline vs hemorrhage",
            x_label: "t within the window [s]",
            y_label: "mL/s × 10 / mmHg",
            series,
        },
    )
}

/// Writes `vitals.csv` and the plots `vitals.png` (MAP, systolic, diastolic, HR, loss) and
/// `hepatic_inflow.png` (beat-mean hepatic inflow) into `dir`.
pub fn write_outputs(samples: &[VitalsSample], dir: &Path) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    crate::output::write_vitals_csv(&dir.join("vitals.csv"), samples).map_err(|e| e.to_string())?;
    let series = |label: &str, y: &dyn Fn(&VitalsSample) -> f64| Series {
        label: label.to_string(),
        points: samples.iter().map(|s| (s.t_s, y(s))).collect(),
        markers: false,
    };
    line_chart(
        &dir.join("vitals.png"),
        &Chart {
            title: "Scripted hemorrhage: vitals of the closed-loop model",
            x_label: "t [s]",
            y_label: "mmHg / beats per min / % blood lost",
            series: vec![
                series("MAP [mmHg]", &|s| s.vitals.map_mmhg),
                series("systolic [mmHg]", &|s| s.vitals.systolic_mmhg),
                series("diastolic [mmHg]", &|s| s.vitals.diastolic_mmhg),
                series("HR [bpm]", &|s| s.vitals.hr_bpm),
                series("blood lost [%]", &|s| 100.0 * s.vitals.blood_lost_fraction),
            ],
        },
    )?;
    line_chart(
        &dir.join("hepatic_inflow.png"),
        &Chart {
            title: "Hepatic arterial inflow to the organ (beat mean; the pulse: hepatic_pulse.png)",
            x_label: "t [s]",
            y_label: "mL/s",
            series: vec![series("beat mean [mL/s]", &|s| s.vitals.hepatic_flow_ml_min / 60.0)],
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hemorrhage_reaches_class_three_and_plots() {
        let s = scripted_hemorrhage(CardioParams::default(), 0.35, 10.0, 600.0, 640.0, 0.5).expect("model");
        let first = s.iter().find(|x| x.t_s >= 9.0).expect("baseline sample").vitals;
        let last = s.last().expect("samples").vitals;
        assert!((85.0..=100.0).contains(&first.map_mmhg), "baseline MAP {}", first.map_mmhg);
        assert!(last.hr_bpm > 120.0 && last.shock_class == 3, "end: {last:?}");
        assert!(last.systolic_mmhg < first.systolic_mmhg);
        let dir = std::env::temp_dir().join(format!("perfuse-hemorrhage-{}", std::process::id()));
        write_outputs(&s, &dir).expect("outputs");
        let w = pulse_windows(CardioParams::default(), 0.35, 10.0, 600.0, 640.0).expect("model");
        assert_eq!(w.len(), 2);
        assert!(w.iter().all(|(_, p)| p.len() >= 1490), "2 ms samples over 3 s");
        // the pulse: several beats per window, the hepatic flow pulsatile (peak well above mean)
        let peak_over_mean = |p: &[(f64, f64, f64)]| {
            let mean = p.iter().map(|x| x.1).sum::<f64>() / p.len() as f64;
            p.iter().map(|x| x.1).fold(0.0, f64::max) / mean
        };
        assert!(peak_over_mean(&w[0].1) > 1.3 && peak_over_mean(&w[1].1) > 1.2);
        write_pulse_plot(&w, &dir).expect("pulse plot");
        for f in ["vitals.csv", "vitals.png", "hepatic_inflow.png", "hepatic_pulse.png"] {
            assert!(dir.join(f).metadata().map(|m| m.len() > 100).unwrap_or(false), "{f}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
