//! Headless runs and what they write: CSV frames (one row per particle), probe time series and
//! `summary.json` (the CLI contract of `perfuse run`, documented in the README); with `--vtk` also
//! ParaView frames (`vtk`).

pub mod vtk;

use crate::scenario::{Phase, Quantity, Scenario};
use crate::sim::{BackendKind, SimError, Simulation, State};
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutputError {
    #[error("cannot write {path}: {source} — check that the directory is writable")]
    Io { path: String, source: std::io::Error },
    #[error(transparent)]
    Sim(#[from] SimError),
    #[error("physiology: {0}")]
    Physiology(#[from] crate::sim::cardio::CardioError),
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> OutputError + '_ {
    move |source| OutputError::Io { path: path.display().to_string(), source }
}

/// Phase masses and counts at the start and end of a run.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct PhaseMass {
    pub liquid_start_kg: f64,
    pub liquid_end_kg: f64,
    pub solid_start_kg: f64,
    pub solid_end_kg: f64,
    pub conserved: bool,
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct ParticleCounts {
    pub liquid: usize,
    pub solid: usize,
    pub boundary: usize,
}

/// `summary.json` of `perfuse run`.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    pub scenario: String,
    pub backend: String,
    pub steps: u64,
    pub simulated_time_s: f64,
    pub wall_time_s: f64,
    pub particle_steps_per_s: f64,
    pub dt_min_s: f64,
    pub dt_max_s: f64,
    /// How many steps each criterion of (2.70) limited Δt.
    pub dt_limited_by: std::collections::BTreeMap<String, u64>,
    pub mass: PhaseMass,
    pub particles: ParticleCounts,
    /// Bonds broken since t = 0 (pairs, Alg. 2); those the relaxation broke are `relaxation.broken_bonds`.
    pub broken_bonds: u64,
    /// Connected components of the solid by intact bonds with at least 8 particles, kinematic
    /// (fixed) particles left out; `solid_fragments` counts the smaller pieces.
    pub solid_components: usize,
    pub solid_fragments: usize,
    /// Liquid particles outside the solid's body or capsule (nˢ < 0.05 at the particle).
    pub liquid_outside: usize,
    /// With a `relaxation` (SPEC §7.5): speeds, top-face sag and liquid outside at t = 0, after it.
    pub relaxation: Option<crate::analysis::relaxation::RelaxationReport>,
    pub particles_outside_domain: usize,
    pub diverged: bool,
    pub divergence: Option<String>,
    pub frames_written: usize,
    /// Simulated time between frame_*.csv files \[s\] (`output.frame_interval`; none: only the final state).
    pub frame_interval_s: Option<f64>,
    /// Simulated time of each frame_NNNNN.csv, in order \[s\].
    pub frame_times_s: Vec<f64>,
    /// With `physiology`: blood lost by the patient \[mL\] (simulated loss × volume_scale), the simulated
    /// volume outside the organ \[m³\], the model's hepatic arterial inflow integrated over the run \[m³\]
    /// and the vitals at the end (also `vitals.csv`, one row per frame).
    pub blood_lost_ml: Option<f64>,
    pub blood_outside_organ_m3: Option<f64>,
    pub model_hepatic_volume_m3: Option<f64>,
    pub vitals_final: Option<crate::sim::cardio::Vitals>,
    /// With `physiology`: the session's metrics — blood lost, peak loss rate, bonds broken, first cut,
    /// hemostasis and the time from the first cut to it (`analysis::session`), from the vitals samples.
    pub session: Option<crate::analysis::session::SessionReport>,
    /// Liquid volume added by the emitters, Σ m/ρ₀ \[m³\] (0 without emitters).
    pub emitted_volume_m3: f64,
    /// With a `Hepatic` emitter: the model's hepatic inflow over the run in simulated volume
    /// (÷ volume_scale) \[m³\], what `emitted_volume_m3` should match.
    pub hepatic_inflow_sim_m3: Option<f64>,
    /// Emitter and sink totals (particles emitted, sunk, per emitter; backlog; capacity).
    pub emitters: crate::sim::EmitTotals,
    /// Initial + emitted − sunk − live liquid particles: 0 when every liquid particle is accounted for.
    pub liquid_balance: i64,
}

/// How long a headless run goes.
#[derive(Clone, Copy, Debug)]
pub enum RunLength {
    Until(f64),
    Steps(u64),
}

/// Options of `perfuse run`.
pub struct RunOptions {
    pub backend: BackendKind,
    pub length: Option<RunLength>,
    pub out: Option<PathBuf>,
    pub progress: bool,
    /// Also write `frame_NNNNN.vtu` beside each CSV frame (`final.vtu` beside `final.csv`) and
    /// `frames.pvd` listing them (`perfuse run --vtk`); needs `out`.
    pub vtk: bool,
    /// Where the scenario's relaxation may come from (`replay::relaxed_cache`: a state an earlier
    /// relaxation of the same scenario by this executable kept, bit for bit the relaxation's); `None`
    /// relaxes every time.
    pub relaxed_cache: Option<crate::replay::relaxed_cache::RelaxedCache>,
    /// Relax even when `relaxed_cache` holds the state, and replace it (`perfuse run --fresh-relaxation`).
    pub fresh_relaxation: bool,
}

/// One probe's per-particle selection.
struct ProbeSel {
    phase: Phase,
    ids: Vec<usize>,
    quantity: Quantity,
}

/// Mean of a quantity over selected particles of a state (in world coordinates for positions).
fn probe_value(state: &State, sel: &ProbeSel, origin: [f64; 3]) -> f64 {
    let set = match sel.phase {
        Phase::Liquid => &state.liquid,
        Phase::Solid => &state.solid,
    };
    if sel.ids.is_empty() {
        return f64::NAN;
    }
    let sum: f64 = sel
        .ids
        .iter()
        .map(|&i| match sel.quantity {
            Quantity::PositionX => set.pos[i].x as f64 + origin[0],
            Quantity::PositionY => set.pos[i].y as f64 + origin[1],
            Quantity::PositionZ => set.pos[i].z as f64 + origin[2],
            Quantity::VelocityX => set.vel[i].x as f64,
            Quantity::VelocityY => set.vel[i].y as f64,
            Quantity::VelocityZ => set.vel[i].z as f64,
            Quantity::Density => set.rho[i] as f64,
            Quantity::Pressure => set.p[i] as f64,
            Quantity::SolidFraction => set.n_s[i] as f64,
            Quantity::LiquidFraction => set.n_l[i] as f64,
        })
        .sum();
    sum / sel.ids.len() as f64
}

/// One row of `vitals.csv`: the patient at simulated time `t_s`.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct VitalsSample {
    pub t_s: f64,
    /// Instantaneous hepatic arterial inflow [mL/s] (pulsatile).
    pub hepatic_inflow_ml_s: f64,
    pub arterial_pressure_mmhg: f64,
    pub vitals: crate::sim::cardio::Vitals,
    /// Bonds broken since t = 0 (0 for the scripted hemorrhage).
    pub broken_bonds: u64,
}

/// Writes `vitals.csv` (headless runs with `physiology`, `perfuse vitals`).
pub fn write_vitals_csv(path: &Path, samples: &[VitalsSample]) -> Result<(), OutputError> {
    let mut text = String::from(
        "t_s,hepatic_inflow_ml_s,map_mmhg,systolic_mmhg,diastolic_mmhg,hr_bpm,cardiac_output_l_min,blood_lost_ml,\
         blood_lost_fraction,shock_class,arterial_pressure_mmhg,blood_volume_ml,hepatic_flow_ml_min\n",
    );
    for s in samples {
        let v = &s.vitals;
        text.push_str(&format!(
            "{:.6},{:.4},{:.3},{:.3},{:.3},{:.3},{:.4},{:.3},{:.5},{},{:.3},{:.2},{:.3}\n",
            s.t_s,
            s.hepatic_inflow_ml_s,
            v.map_mmhg,
            v.systolic_mmhg,
            v.diastolic_mmhg,
            v.hr_bpm,
            v.cardiac_output_l_min,
            v.blood_lost_ml,
            v.blood_lost_fraction,
            v.shock_class,
            s.arterial_pressure_mmhg,
            v.blood_volume_ml,
            v.hepatic_flow_ml_min
        ));
    }
    std::fs::write(path, text).map_err(io_err(path))
}

/// Writes one CSV frame: phase,id,x,y,z,vx,vy,vz,density,n_s,n_l,pressure (SI, world coordinates).
pub fn write_frame_csv(path: &Path, state: &State, origin: [f64; 3]) -> Result<(), OutputError> {
    let f = std::fs::File::create(path).map_err(io_err(path))?;
    let mut w = std::io::BufWriter::new(f);
    let mut text = String::with_capacity(100 * (state.liquid.len() + state.solid.len()) + 64);
    text.push_str("phase,id,x,y,z,vx,vy,vz,density,n_s,n_l,pressure\n");
    for (name, set) in [("liquid", &state.liquid), ("solid", &state.solid)] {
        for i in 0..set.len() {
            let p = set.pos[i];
            let v = set.vel[i];
            text.push_str(&format!(
                "{name},{},{:.9e},{:.9e},{:.9e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e}\n",
                set.id[i],
                p.x as f64 + origin[0],
                p.y as f64 + origin[1],
                p.z as f64 + origin[2],
                v.x,
                v.y,
                v.z,
                set.rho[i],
                set.n_s[i],
                set.n_l[i],
                set.p[i]
            ));
        }
    }
    w.write_all(text.as_bytes()).map_err(io_err(path))?;
    w.flush().map_err(io_err(path))
}

/// Particles (liquid + solid) outside the domain box.
pub fn count_outside(state: &State, sim: &Simulation) -> usize {
    let p = sim.params();
    let d = p.dim.n();
    let out = |x: glam::Vec3| (0..d).any(|a| !p.periodic[a] && (x[a] < p.domain_min[a] || x[a] > p.domain_max[a]));
    state.liquid.pos.iter().chain(state.solid.pos.iter()).filter(|x| out(**x)).count()
}

/// Runs a scenario headless: relaxation, steps, frames, probes and the summary.
pub fn run_headless(scenario: &Scenario, opts: &RunOptions) -> Result<Summary, OutputError> {
    let started = Instant::now();
    let mut sim = Simulation::new(scenario, opts.backend)?;
    if let Some(dir) = &opts.out {
        std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    }
    let origin = sim.params().origin;
    let bar = if opts.progress { Some(progress_bar()) } else { None };
    let mut divergence = None;
    let relaxing = scenario.relaxation.as_ref().filter(|r| r.duration > 0.0);
    let unrelaxed = if relaxing.is_some() { Some(sim.read_state()?) } else { None };
    let cache = opts.relaxed_cache.as_ref();
    match crate::replay::relaxed_cache::relax_with_cache(cache, opts.fresh_relaxation, scenario, &mut sim, |_| {}) {
        Ok(Some(f)) if opts.progress => {
            eprintln!("relaxed state from {} (--fresh-relaxation relaxes again)", f.display())
        }
        Ok(_) => {}
        Err(e) => divergence = Some(e.to_string()),
    }
    let s0 = sim.read_state()?;
    let relaxation = relaxing.zip(unrelaxed.as_ref()).map(|(r, before)| {
        let g = scenario.gravity;
        let g = glam::Vec3::new(g[0] as f32, g[1] as f32, g[2] as f32);
        crate::analysis::relaxation::measure(before, &s0, r.duration, g, sim.params().dx_solid)
    });
    // The patient (issue 7): sampled with every state read back (frames, probes, the end).
    let rho0_l = scenario.liquid.as_ref().map_or(1000.0, |l| l.density);
    let mut patient = scenario.physiology.as_ref().map(crate::sim::physiology::Patient::new).transpose()?;
    let mut vitals_rows: Vec<VitalsSample> = Vec::new();
    // Bonds are counted from t = 0: what the relaxation broke is in the `relaxation` block.
    let broken_at_zero = s0.broken_bonds();
    fn sample_patient(
        patient: &mut Option<crate::sim::physiology::Patient>,
        st: &State,
        rho0_l: f64,
        broken_at_zero: u64,
        rows: &mut Vec<VitalsSample>,
    ) {
        if let Some(p) = patient {
            let vitals = p.update(st, rho0_l);
            rows.push(VitalsSample {
                t_s: st.t,
                broken_bonds: st.broken_bonds().saturating_sub(broken_at_zero),
                hepatic_inflow_ml_s: p.model.hepatic_flow_m3_s() * 1e6,
                arterial_pressure_mmhg: p.model.arterial_pressure_mmhg(),
                vitals,
            });
        }
    }
    // The hepatic emitters follow the patient's model (tables renewed a horizon ahead).
    let hepatic = sim.hepatic_emitters();
    let drive_inflow = |sim: &mut Simulation, patient: &mut Option<crate::sim::physiology::Patient>| {
        if let Some(p) = patient
            && !hepatic.is_empty()
            && sim.time() + 0.5 * crate::sim::physiology::INFLOW_HORIZON_S >= p.inflow_until()
        {
            let t = sim.time();
            for &k in &hepatic {
                let cmd = p.inflow(k, t, t.max(0.0) + crate::sim::physiology::INFLOW_HORIZON_S);
                sim.apply(&cmd)?;
            }
        }
        Ok::<(), crate::sim::SimError>(())
    };
    sample_patient(&mut patient, &s0, rho0_l, broken_at_zero, &mut vitals_rows);
    let d = scenario.dimensions;
    let probes: Vec<ProbeSel> = scenario
        .output
        .probes
        .iter()
        .map(|pr| {
            let set = match pr.phase {
                Phase::Liquid => &s0.liquid,
                Phase::Solid => &s0.solid,
            };
            let ids = (0..set.len()).filter(|&i| pr.region.contains(sim.params().to_world(set.pos[i]), d)).collect();
            ProbeSel { phase: pr.phase, ids, quantity: pr.quantity }
        })
        .collect();
    let (t_end, max_steps) = match opts.length {
        Some(RunLength::Until(t)) => (t, u64::MAX),
        Some(RunLength::Steps(n)) => (f64::INFINITY, n),
        None => (scenario.duration, u64::MAX),
    };
    let frame_dt = scenario.output.frame_interval;
    let probe_dt = frame_dt.unwrap_or(f64::INFINITY).min(if t_end.is_finite() { t_end / 200.0 } else { f64::INFINITY });
    let mut frames = 0usize;
    let mut frame_times: Vec<f64> = Vec::new();
    let mut probe_rows: Vec<(f64, Vec<f64>)> = Vec::new();
    // ParaView frames beside the CSV ones; the collection is valid after every frame, so a run that
    // stops early still has an index.
    let mut vtk = match &opts.out {
        Some(dir) if opts.vtk => Some(vtk::VtkSeries::create(dir)?),
        _ => None,
    };
    let params = sim.params().clone();
    let mut write_frame = |state: &State, frames: &mut usize, times: &mut Vec<f64>| -> Result<(), OutputError> {
        if let Some(dir) = &opts.out {
            write_frame_csv(&dir.join(format!("frame_{:05}.csv", *frames)), state, origin)?;
        }
        if let Some(series) = &mut vtk {
            series.write(&format!("frame_{:05}.vtu", *frames), state, &params)?;
        }
        *frames += 1;
        times.push(state.t);
        Ok(())
    };
    if frame_dt.is_some() {
        write_frame(&s0, &mut frames, &mut frame_times)?;
    }
    probe_rows.push((s0.t, probes.iter().map(|p| probe_value(&s0, p, origin)).collect()));
    let mut next_frame = frame_dt.unwrap_or(f64::INFINITY);
    let mut next_probe = probe_dt;
    let mut steps = 0u64;
    let run_start = Instant::now();
    let mut last_bar = Instant::now();
    let steps0 = sim.stats().steps;
    while divergence.is_none() && sim.time() < t_end && steps < max_steps {
        // One chunk (one GPU batch) up to the next frame, probe or end time: a frame or probe is taken
        // at the first step at or after its time, as with single steps.
        drive_inflow(&mut sim, &mut patient)?;
        let target = (next_frame - 1e-12).min(next_probe - 1e-12).min(t_end);
        let chunk = (max_steps - steps).min(u64::from(crate::sim::ADVANCE_CHUNK)) as u32;
        let result = if target > sim.time() { sim.advance(chunk, target) } else { sim.advance(1, f64::INFINITY) };
        steps = sim.stats().steps - steps0;
        match result {
            Ok(adv) => {
                let t = adv.t;
                if t >= next_frame - 1e-12 || t >= next_probe - 1e-12 {
                    let st = sim.read_state()?;
                    sample_patient(&mut patient, &st, rho0_l, broken_at_zero, &mut vitals_rows);
                    if t >= next_probe - 1e-12 {
                        probe_rows.push((st.t, probes.iter().map(|p| probe_value(&st, p, origin)).collect()));
                        while next_probe <= t {
                            next_probe += probe_dt;
                        }
                    }
                    if t >= next_frame - 1e-12 {
                        write_frame(&st, &mut frames, &mut frame_times)?;
                        while next_frame <= t {
                            next_frame += frame_dt.unwrap_or(f64::INFINITY);
                        }
                    }
                }
                if let Some(b) = &bar
                    && last_bar.elapsed().as_millis() > 200
                {
                    last_bar = Instant::now();
                    let frac = if t_end.is_finite() { t / t_end } else { steps as f64 / max_steps as f64 };
                    let limit = crate::sim::DtLimit::ALL
                        .iter()
                        .zip(adv.limited_by)
                        .max_by_key(|(_, n)| *n)
                        .map_or("", |(l, _)| l.name());
                    b.set_position((frac.clamp(0.0, 1.0) * 1000.0) as u64);
                    b.set_message(format!("t = {t:.4} s, dt = {:.2e} s ({limit})", adv.dt_max));
                }
            }
            Err(e) => divergence = Some(e.to_string()),
        }
    }
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    let wall_run = run_start.elapsed().as_secs_f64();
    let fin = sim.read_state()?;
    if vitals_rows.last().is_none_or(|r| fin.t > r.t_s) {
        sample_patient(&mut patient, &fin, rho0_l, broken_at_zero, &mut vitals_rows);
    }
    let (model_hepatic, lost_sim) = patient.as_ref().map_or((None, None), |p| {
        // the model runs ahead of the organ when it drives the inflow: its integral at the end time
        let v = p.hepatic_inflow_sim_m3(fin.t).map_or(p.model.hepatic_volume_m3(), |v| v * p.volume_scale());
        (Some(v), Some(p.lost_simulated_m3()))
    });
    let hepatic_inflow_sim =
        if hepatic.is_empty() { None } else { patient.as_ref().and_then(|p| p.hepatic_inflow_sim_m3(fin.t)) };
    let emit_totals = sim.emit_totals()?;
    let liquid_balance =
        s0.liquid.len() as i64 + emit_totals.emitted as i64 - emit_totals.sunk as i64 - fin.liquid.len() as i64;
    if let Some(dir) = &opts.out
        && !vitals_rows.is_empty()
    {
        write_vitals_csv(&dir.join("vitals.csv"), &vitals_rows)?;
    }
    // The final state: frame_00000.csv when the scenario asks for no frames; otherwise `final.csv`
    // when it falls between frame times, so that frame_*.csv stay uniformly spaced (DMD relies on it).
    if frame_dt.is_none() {
        write_frame(&fin, &mut frames, &mut frame_times)?;
    } else if frame_times.last().is_none_or(|t| fin.t > t + 1e-12)
        && let Some(dir) = &opts.out
    {
        write_frame_csv(&dir.join("final.csv"), &fin, origin)?;
        // ParaView needs no uniform spacing: the final state is the collection's last entry.
        if let Some(series) = &mut vtk {
            series.write("final.vtu", &fin, &params)?;
        }
    }
    if let Some(series) = vtk {
        series.finish()?;
    }
    if let Some(dir) = &opts.out
        && !scenario.output.probes.is_empty()
    {
        let path = dir.join("probes.csv");
        let mut text = String::from("t");
        for p in &scenario.output.probes {
            text.push(',');
            text.push_str(&p.name);
        }
        text.push('\n');
        for (t, vals) in &probe_rows {
            text.push_str(&format!("{t:.9e}"));
            for v in vals {
                text.push_str(&format!(",{v:.9e}"));
            }
            text.push('\n');
        }
        std::fs::write(&path, text).map_err(io_err(&path))?;
    }
    let n_particles = fin.liquid.len() + fin.solid.len();
    let stats = sim.stats().clone();
    let mass = PhaseMass {
        liquid_start_kg: s0.liquid.total_mass(),
        liquid_end_kg: fin.liquid.total_mass(),
        solid_start_kg: s0.solid.total_mass(),
        solid_end_kg: fin.solid.total_mass(),
        // with emitters or sinks the liquid changes by what they added and removed, to the particle
        conserved: s0.solid.total_mass() == fin.solid.total_mass()
            && if emit_totals.emitted + emit_totals.sunk > 0 {
                liquid_balance == 0
            } else {
                s0.liquid.total_mass() == fin.liquid.total_mass()
            },
    };
    let components = fin.solid_component_sizes();
    let summary = Summary {
        scenario: scenario.name.clone(),
        backend: format!("{:?}", opts.backend).to_lowercase(),
        steps,
        simulated_time_s: fin.t,
        wall_time_s: started.elapsed().as_secs_f64(),
        particle_steps_per_s: if wall_run > 0.0 { steps as f64 * n_particles as f64 / wall_run } else { 0.0 },
        dt_min_s: if stats.dt_min.is_finite() { stats.dt_min } else { 0.0 },
        dt_max_s: stats.dt_max,
        dt_limited_by: stats.dt_limited_by,
        mass,
        particles: ParticleCounts {
            liquid: fin.liquid.len(),
            solid: fin.solid.len(),
            boundary: fin.boundary.pos.len(),
        },
        broken_bonds: fin.broken_bonds().saturating_sub(broken_at_zero),
        solid_components: components.iter().filter(|&&c| c >= crate::sim::state::MIN_COMPONENT).count(),
        solid_fragments: components.iter().filter(|&&c| c < crate::sim::state::MIN_COMPONENT).count(),
        liquid_outside: fin.liquid_outside(),
        relaxation,
        particles_outside_domain: count_outside(&fin, &sim),
        diverged: divergence.is_some(),
        divergence,
        frames_written: frames,
        frame_interval_s: frame_dt,
        frame_times_s: frame_times,
        blood_lost_ml: vitals_rows.last().map(|r| r.vitals.blood_lost_ml),
        blood_outside_organ_m3: lost_sim,
        model_hepatic_volume_m3: model_hepatic,
        vitals_final: vitals_rows.last().map(|r| r.vitals),
        session: scenario.physiology.as_ref().map(|_| {
            let mut m = crate::analysis::session::SessionMetrics::default();
            for r in &vitals_rows {
                m.push(r.t_s, r.vitals.blood_lost_ml, r.broken_bonds);
            }
            m.report().clone()
        }),
        emitted_volume_m3: emit_totals.emitted_volume_m3,
        hepatic_inflow_sim_m3: hepatic_inflow_sim,
        emitters: emit_totals,
        liquid_balance,
    };
    if let Some(dir) = &opts.out {
        let path = dir.join("summary.json");
        let text = serde_json::to_string_pretty(&summary)
            .map_err(|e| OutputError::Io { path: path.display().to_string(), source: std::io::Error::other(e) })?;
        std::fs::write(&path, text).map_err(io_err(&path))?;
    }
    Ok(summary)
}

/// A progress bar with ETA on stderr (hidden when stderr is not a terminal).
pub fn progress_bar() -> indicatif::ProgressBar {
    let b = indicatif::ProgressBar::new(1000);
    if let Ok(style) = indicatif::ProgressStyle::with_template("{bar:40} {percent:>3}% ETA {eta} {msg}") {
        b.set_style(style);
    }
    b
}
