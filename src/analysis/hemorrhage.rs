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

/// Writes `vitals.csv` and the plots `vitals.png` (MAP, systolic, diastolic, HR) and
/// `hepatic_inflow.png` into `dir`.
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
            title: "Hepatic arterial inflow to the organ",
            x_label: "t [s]",
            y_label: "mL/s (instantaneous) and mL/min ÷ 60 (beat mean)",
            series: vec![
                series("instantaneous [mL/s]", &|s| s.hepatic_inflow_ml_s),
                series("beat mean [mL/s]", &|s| s.vitals.hepatic_flow_ml_min / 60.0),
            ],
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
        for f in ["vitals.csv", "vitals.png", "hepatic_inflow.png"] {
            assert!(dir.join(f).metadata().map(|m| m.len() > 100).unwrap_or(false), "{f}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
