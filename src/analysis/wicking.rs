//! The wicking validation case (`perfuse validate --case wicking`; SPEC §7.12, §8.2 W1–W3): the three
//! fabric scenarios of thesis §4.3 run for their 2 s and measured against the volume balance
//! A_ref = V_d/(nˡ_eq t_eff). `--quick` re-grids them to SPEC §8.2's reduced set (100 × 100 fabric
//! particles at 5Δx_s, a 1021-particle drop): ≈ 15 min per case on two CPU cores. The standard run is
//! the thesis resolution (258 025 particles, 3·10⁵ steps): a GPU run.

use super::plot::{Chart, Series};
use super::validate::{CaseResult, Invariants, ValidationError, advance_to, at_least, at_most, plot_into};
use super::wetting;
use crate::scenario::Scenario;
use crate::sim::{BackendKind, Simulation};
use std::path::Path;
use std::time::Instant;

const SPREAD: &str = include_str!("../../assets/scenarios/fabric_spread.ron");
const WET: &str = include_str!("../../assets/scenarios/fabric_wet.ron");
const DRIP: &str = include_str!("../../assets/scenarios/fabric_drip.ron");

/// What one case measured at the end of its run.
struct Outcome {
    /// Stain area over A_ref at the end.
    area_ratio: f64,
    area: f64,
    centroid_offset: f64,
    /// 99th percentile of the liquid's speed [m/s].
    v99: f64,
    /// Fraction of the liquid mass below z = −R_×.
    below: f64,
    /// (t, A/A_ref) samples.
    history: Vec<(f64, f64)>,
    invariants: Invariants,
    resolution: String,
}

fn run_case(
    text: &str,
    file: &str,
    quick: bool,
    backend: BackendKind,
    progress: bool,
) -> Result<Outcome, ValidationError> {
    let ov: Vec<String> = if quick {
        vec!["numerics.dx_solid=0.00026".into(), "numerics.dx_liquid=0.00024191".into()]
    } else {
        Vec::new()
    };
    let sc = Scenario::from_str_with_overrides(text, &format!("assets/scenarios/{file}"), &ov)?;
    let n_eq = sc
        .liquid
        .as_ref()
        .and_then(|l| l.c1_from_equilibrium)
        .map(|e| e.liquid_fraction)
        .ok_or_else(|| ValidationError::Io { path: file.into(), message: "no c1_from_equilibrium".into() })?;
    let mut sim = Simulation::new(&sc, backend)?;
    let p = sim.params().clone();
    let r_x = p.k_cross.r as f64;
    let sheet_z = p.to_sim([0.0; 3]).z as f64;
    let s0 = sim.read_state()?;
    let volume = s0.liquid.total_mass() / p.rho0_l as f64;
    let a_ref = wetting::reference_stain_area(volume, n_eq, r_x, 3);
    let resolution = format!("{} liquid + {} fabric particles", s0.liquid.len(), s0.solid.len());
    let mut inv = Invariants::default();
    inv.check(&sim, &s0);
    let mut history = Vec::new();
    let bar = progress.then(crate::output::progress_bar);
    let sample = 0.05f64;
    let mut next = sample;
    while sim.time() < sc.duration - 1e-9 {
        let t = advance_to(&mut sim, next.min(sc.duration))?;
        if t >= next - 1e-9 {
            let s = sim.read_state()?;
            let stain = wetting::stain(&s.solid.pos, &s.solid.n_l, n_eq, p.dx_solid as f64, 3);
            history.push((t, stain.area / a_ref));
            inv.check(&sim, &s);
            next += sample;
        }
        if let Some(b) = &bar {
            b.set_position((t / sc.duration * 1000.0) as u64);
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let s = sim.read_state()?;
    let stain = wetting::stain(&s.solid.pos, &s.solid.n_l, n_eq, p.dx_solid as f64, 3);
    let mut speeds: Vec<f64> = s.liquid.vel.iter().map(|v| v.length() as f64).collect();
    speeds.sort_by(f64::total_cmp);
    let v99 = speeds.get((0.99 * speeds.len() as f64) as usize).copied().unwrap_or(f64::NAN);
    let total = s.liquid.total_mass();
    let below = s
        .liquid
        .pos
        .iter()
        .zip(&s.liquid.mass)
        .filter(|(x, _)| (x.z as f64 - sheet_z) < -r_x)
        .fold(0.0, |acc, (_, m)| acc + *m as f64)
        / total;
    log::info!(
        "{file}: stain {:.1} mm² = {:.2} A_ref, centroid ({:.2}, {:.2}) mm, v99 {:.2} mm/s, below {:.3}",
        stain.area * 1e6,
        stain.area / a_ref,
        stain.centroid[0] * 1e3,
        stain.centroid[1] * 1e3,
        v99 * 1e3,
        below
    );
    Ok(Outcome {
        area_ratio: stain.area / a_ref,
        area: stain.area,
        centroid_offset: (stain.centroid[0].powi(2) + stain.centroid[1].powi(2)).sqrt(),
        v99,
        below,
        history,
        invariants: inv,
        resolution,
    })
}

/// W1–W3 of SPEC §7.12: rows for `report.json` and `wicking_stain.png`.
pub fn validate(
    quick: bool,
    backend: BackendKind,
    out: &Path,
    progress: bool,
) -> Result<Vec<CaseResult>, ValidationError> {
    let started = Instant::now();
    let c1 = run_case(SPREAD, "fabric_spread.ron", quick, backend, progress)?;
    let c2 = run_case(WET, "fabric_wet.ron", quick, backend, progress)?;
    let c3 = run_case(DRIP, "fabric_drip.ron", quick, backend, progress)?;
    plot_into(
        out,
        "wicking_stain.png",
        &Chart {
            title: "Wicking into a fabric: stain area / A_ref (thesis section 4.3)",
            x_label: "t [s]",
            y_label: "A / A_ref",
            series: vec![
                Series { label: "case 1 (n_eq 0.5)".into(), points: c1.history.clone(), markers: true },
                Series { label: "case 2 (n_eq 0.15)".into(), points: c2.history.clone(), markers: true },
                Series { label: "case 3 (n_eq 0.15, gamma / 10)".into(), points: c3.history.clone(), markers: true },
            ],
        },
    )?;
    let wall = started.elapsed().as_secs_f64();
    let res = &c1.resolution;
    Ok(vec![
        // (2) A(2 s) ∈ [0.6, 1.6]·A_ref, written as |A/A_ref − 1.1| ≤ 0.5.
        at_most("wicking", res, "case1_abs(A_over_Aref-1.1)", (c1.area_ratio - 1.1).abs(), 0.5, wall),
        at_most("wicking", res, "case1_stain_centroid_offset_m", c1.centroid_offset, 1e-3, wall),
        at_most("wicking", res, "case1_v99_m_per_s", c1.v99, 1e-3, wall),
        // (3) A_case2 ≥ 2·A_case1.
        at_least("wicking", res, "A_case2_over_A_case1", c2.area / c1.area.max(f64::MIN_POSITIVE), 2.0, wall),
        // (4) Case 3: ≥ 5 % of the liquid below z = −R_×; case 2: ≤ 1 %.
        at_least("wicking", res, "case3_mass_fraction_below", c3.below, 0.05, wall),
        at_most("wicking", res, "case2_mass_fraction_below", c2.below, 0.01, wall),
        // (1) Mass conservation and the other invariants.
        c1.invariants.result("wicking case 1", res, wall),
        c2.invariants.result("wicking case 2", res, wall),
        c3.invariants.result("wicking case 3", res, wall),
    ])
}
