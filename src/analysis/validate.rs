//! The validation cases of SPEC.md §7 (issue: core), each run against its analytic reference:
//! start-up Poiseuille (§7.1), cantilever free vibration (§7.2), Brinkman flow (§7.3), convergence
//! (§7.4) and a hydrostatic column. `--quick` runs the reduced (CI) resolutions; the default runs the
//! standard (thesis-resolution) configurations. Every case also checks the invariants: phase masses
//! constant, no NaN, no particle outside the domain.
//!
//! The physical parameters come from the shipped scenario files (embedded); resolution changes are
//! applied as `--set`-style overrides, so a case and `perfuse run` of its file are the same setup.

use super::analytic::{brinkman_steady, cantilever_omega1, poiseuille_startup, young_poisson};
use super::plot::{Chart, Series, line_chart};
use super::relaxation::RelaxWith;
use crate::scenario::{Scenario, ScenarioError};
use crate::sim::{BackendKind, SimError, Simulation, State};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

pub const POISEUILLE: &str = include_str!("../../assets/scenarios/poiseuille.ron");
pub const BRINKMAN: &str = include_str!("../../assets/scenarios/brinkman.ron");
pub const HYDROSTATIC: &str = include_str!("../../assets/scenarios/hydrostatic.ron");
pub const CANTILEVER: &str = include_str!("../../assets/scenarios/cantilever.ron");
pub const CANTILEVER_2D: &str = include_str!("../../assets/scenarios/cantilever_2d.ron");

/// The cases `perfuse validate` runs by default, in order.
pub const CASES: [&str; 5] = ["poiseuille", "brinkman", "convergence", "hydrostatic", "cantilever"];

/// Cases run only when named with `--case` (each is tens of minutes on a CPU): the wicking set of SPEC
/// §7.12 (W1–W3), the liver cut by the scalpel (SPEC §9.3: L1 and L2, or one of them alone) and the
/// projectile (SPEC §7.10), the syringe (SPEC §7.8), the DMD of the oscillating wall and the broken dam (SPEC §7.13–7.14),
/// the intact capsule over 10⁴ steps, hanging and indented (issue 6 §1), and the default liver at rest
/// (issue 6 §4).
pub const EXTRA_CASES: [&str; 9] = [
    "wicking",
    "liver_scalpel",
    "liver_scalpel_L1",
    "liver_scalpel_L2",
    "projectile",
    "syringe",
    "dmd",
    "capsule",
    "liver_rest",
];

/// The cases `--set` may edit: each runs one scenario file (re-gridded by its preset).
pub const SET_CASES: [&str; 7] =
    ["liver_scalpel", "liver_scalpel_L1", "liver_scalpel_L2", "projectile", "syringe", "liver_rest", "capsule"];

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ValidationError {
    #[error(
        "unknown validation case `{0}` — use one of: poiseuille, brinkman, convergence, hydrostatic, cantilever, wicking, liver_scalpel, liver_scalpel_L1, liver_scalpel_L2, projectile, syringe, dmd, capsule, liver_rest"
    )]
    UnknownCase(String),
    #[error(
        "--set applies to one named case of liver_scalpel, liver_scalpel_L1, liver_scalpel_L2, projectile or syringe (whose scenario files it edits), not to {0} — run `perfuse run FILE --set …` to probe another scenario"
    )]
    SetNotSupported(String),
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error(transparent)]
    Sim(#[from] SimError),
    #[error("cannot write {path}: {message}")]
    Io { path: String, message: String },
}

/// One row of `report.json`.
#[derive(Clone, Debug, Serialize)]
pub struct CaseResult {
    pub name: String,
    pub resolution: String,
    pub metric: String,
    pub value: f64,
    pub tolerance: f64,
    pub pass: bool,
    pub wall_time_s: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct Report {
    pub quick: bool,
    pub backend: String,
    /// The `--set FIELD=VALUE` edits applied on top of the case's own (empty for the standard figures).
    pub overrides: Vec<String>,
    pub cases: Vec<CaseResult>,
}

struct Ctx<'a> {
    quick: bool,
    backend: BackendKind,
    out: &'a Path,
    progress: bool,
    relax: RelaxWith<'a>,
}

/// A metric with a lower bound (value ≥ tolerance passes).
pub(crate) fn at_least(
    name: &str,
    resolution: &str,
    metric: &str,
    value: f64,
    tolerance: f64,
    wall: f64,
) -> CaseResult {
    row(name, resolution, metric, value, tolerance, value >= tolerance, wall)
}

/// A metric with an upper bound (value ≤ tolerance passes).
pub(crate) fn at_most(name: &str, resolution: &str, metric: &str, value: f64, tolerance: f64, wall: f64) -> CaseResult {
    row(name, resolution, metric, value, tolerance, value <= tolerance, wall)
}

/// A figure reported without a bound: metric `"<metric> (reported)"`, tolerance NaN, always passes.
pub(crate) fn reported(name: &str, resolution: &str, metric: &str, value: f64, wall: f64) -> CaseResult {
    CaseResult {
        name: name.into(),
        resolution: resolution.into(),
        metric: format!("{metric} (reported)"),
        value,
        tolerance: f64::NAN,
        pass: true,
        wall_time_s: wall,
    }
}

/// One row; a non-finite value never passes.
fn row(name: &str, resolution: &str, metric: &str, value: f64, tolerance: f64, within: bool, wall: f64) -> CaseResult {
    CaseResult {
        name: name.into(),
        resolution: resolution.into(),
        metric: metric.into(),
        value,
        tolerance,
        pass: value.is_finite() && within,
        wall_time_s: wall,
    }
}

/// Runs the selected (or all) cases, writes `report.json` and the PNG plots into `out`. `overrides`
/// (`--set FIELD=VALUE`, as for `perfuse run`) edit the scenario of a named liver_scalpel, projectile or
/// syringe case after its preset's own edits — a probe of a parameter against the case's criteria.
/// `relax` says where the cases that relax take their relaxed state from (`relaxation::relax_cached`:
/// the CLI passes the user's relaxed-state cache; `RelaxWith::default()` relaxes every time).
pub fn run_validation(
    case: Option<&str>,
    quick: bool,
    out: &Path,
    backend: BackendKind,
    progress: bool,
    overrides: &[String],
    relax: RelaxWith<'_>,
) -> Result<Report, ValidationError> {
    if let Some(c) = case
        && !CASES.contains(&c)
        && !EXTRA_CASES.contains(&c)
    {
        return Err(ValidationError::UnknownCase(c.to_string()));
    }
    if !overrides.is_empty() && !matches!(case, Some(c) if SET_CASES.contains(&c)) {
        return Err(ValidationError::SetNotSupported(case.unwrap_or("all standard cases").to_string()));
    }
    std::fs::create_dir_all(out)
        .map_err(|e| ValidationError::Io { path: out.display().to_string(), message: e.to_string() })?;
    let ctx = Ctx { quick, backend, out, progress, relax };
    let mut cases = Vec::new();
    let selected: Vec<&str> = match case {
        Some(c) => vec![c],
        None => CASES.to_vec(),
    };
    for name in selected {
        if progress {
            eprintln!("validating {name} ({})…", if quick { "quick" } else { "standard" });
        }
        let rows = match name {
            "poiseuille" => poiseuille(&ctx)?,
            "brinkman" => brinkman(&ctx)?,
            "convergence" => convergence(&ctx)?,
            "hydrostatic" => hydrostatic(&ctx)?,
            "wicking" => super::wicking::validate(ctx.quick, ctx.backend, ctx.out, ctx.progress)?,
            "liver_scalpel" | "liver_scalpel_L1" | "liver_scalpel_L2" => {
                use super::scalpel::Variant;
                let variants: &[Variant] = match name {
                    "liver_scalpel_L1" => &[Variant::Thesis],
                    "liver_scalpel_L2" => &[Variant::Product],
                    _ => &[Variant::Product, Variant::Thesis],
                };
                super::scalpel::validate(variants, ctx.quick, ctx.backend, ctx.out, ctx.progress, overrides, ctx.relax)?
            }
            "projectile" => {
                super::projectile::validate(ctx.quick, ctx.backend, ctx.out, ctx.progress, overrides, ctx.relax)?
            }
            "syringe" => super::syringe::validate(ctx.quick, ctx.backend, ctx.out, ctx.progress, overrides, ctx.relax)?,
            "dmd" => super::dmd_cases::validate(ctx.quick, ctx.backend, ctx.out, ctx.progress)?,
            "capsule" => super::capsule::validate(ctx.quick, ctx.backend, ctx.out, ctx.progress, overrides)?,
            "liver_rest" => {
                super::liver_rest::validate(ctx.quick, ctx.backend, ctx.out, ctx.progress, overrides, ctx.relax)?
            }
            _ => cantilever(&ctx)?,
        };
        cases.extend(rows);
    }
    let report = Report { quick, backend: format!("{backend:?}").to_lowercase(), overrides: overrides.to_vec(), cases };
    let path = out.join("report.json");
    let text = serde_json::to_string_pretty(&report)
        .map_err(|e| ValidationError::Io { path: path.display().to_string(), message: e.to_string() })?;
    std::fs::write(&path, text)
        .map_err(|e| ValidationError::Io { path: path.display().to_string(), message: e.to_string() })?;
    Ok(report)
}

fn plot(ctx: &Ctx, file: &str, chart: &Chart) -> Result<PathBuf, ValidationError> {
    plot_into(ctx.out, file, chart)
}

pub(crate) fn plot_into(out: &Path, file: &str, chart: &Chart) -> Result<PathBuf, ValidationError> {
    let path = out.join(file);
    line_chart(&path, chart).map_err(|message| ValidationError::Io { path: path.display().to_string(), message })?;
    Ok(path)
}

/// Invariants of every case: masses constant, all finite, nothing outside the (non-periodic) domain.
#[derive(Default)]
pub(crate) struct Invariants {
    mass0: Option<(f64, f64)>,
    violations: Vec<String>,
    /// Emitters and sinks change the liquid's mass (their balance is checked on its own).
    liquid_exchanged: bool,
    /// Splashes may leave the domain (SPEC §7.5's invariants do not forbid it).
    open_domain: bool,
}

impl Invariants {
    /// Invariants of a run whose emitters or sinks add or remove liquid: only the solid's mass is
    /// held constant.
    pub(crate) fn with_emitters() -> Invariants {
        Invariants { liquid_exchanged: true, ..Default::default() }
    }

    /// The same, not counting particles that left the domain (a splash), which SPEC §7.5's common
    /// invariants of the medical cases do not forbid.
    pub(crate) fn open_domain(self) -> Invariants {
        Invariants { open_domain: true, ..self }
    }

    pub(crate) fn check(&mut self, sim: &Simulation, s: &State) {
        let m = (if self.liquid_exchanged { 0.0 } else { s.liquid.total_mass() }, s.solid.total_mass());
        match self.mass0 {
            None => self.mass0 = Some(m),
            Some(m0) if m0 != m => self.violations.push(format!("mass changed at t = {:.4}: {m0:?} → {m:?}", s.t)),
            _ => {}
        }
        let finite = |p: &crate::sim::state::PhaseState| {
            p.pos.iter().chain(p.vel.iter()).all(|v| v.is_finite()) && p.rho.iter().all(|r| r.is_finite())
        };
        if !finite(&s.liquid) || !finite(&s.solid) {
            self.violations.push(format!("non-finite state at t = {:.4}", s.t));
        }
        let outside = crate::output::count_outside(s, sim);
        if outside > 0 && !self.open_domain {
            self.violations.push(format!("{outside} particles outside the domain at t = {:.4}", s.t));
        }
    }

    /// Number of violations so far.
    pub(crate) fn count(&self) -> usize {
        self.violations.len()
    }

    /// The first violation, if any.
    pub(crate) fn first(&self) -> Option<String> {
        self.violations.first().cloned()
    }

    pub(crate) fn result(&self, name: &str, resolution: &str, wall: f64) -> CaseResult {
        if let Some(v) = self.violations.first() {
            log::warn!("{name}: invariant violated: {v}");
        }
        at_most(name, resolution, "invariant_violations", self.violations.len() as f64, 0.0, wall)
    }
}

fn load(text: &str, file: &str, overrides: &[String]) -> Result<Scenario, ValidationError> {
    Ok(Scenario::from_str_with_overrides(text, &format!("assets/scenarios/{file}"), overrides)?)
}

/// Overrides that re-grid the 2-D channel of the Poiseuille/Brinkman files: `ny` rows across 2H,
/// `nx` columns, 3 wall rows per side (`solid`: also the Brinkman skeleton and its fixed region).
pub fn channel_overrides(ny: usize, nx: usize, solid: bool) -> Vec<String> {
    let h = 0.01f64;
    let dx = 2.0 * h / ny as f64;
    let lx = nx as f64 * dx;
    let wall = h + 3.0 * dx;
    let mut ov = vec![
        format!("numerics.dx_liquid={dx}"),
        format!("domain.min=[0.0, {}, 0.0]", -(wall + dx).max(0.0125)),
        format!("domain.max=[{lx}, {}, 0.0]", (wall + dx).max(0.0125)),
        format!("particles.0.max=[{lx}, {h}, 0.0]"),
        format!("boundaries.0.shape.min=[0.0, {h}, 0.0]"),
        format!("boundaries.0.shape.max=[{lx}, {wall}, 0.0]"),
        format!("boundaries.0.spacing={dx}"),
        format!("boundaries.1.shape.min=[0.0, {}, 0.0]", -wall),
        format!("boundaries.1.shape.max=[{lx}, {}, 0.0]", -h),
        format!("boundaries.1.spacing={dx}"),
    ];
    if solid {
        ov.push(format!("numerics.dx_solid={dx}"));
        ov.push(format!("particles.1.min=[0.0, {}, 0.0]", -wall));
        ov.push(format!("particles.1.max=[{lx}, {wall}, 0.0]"));
        ov.push(format!("fixed_regions.0.min=[-1.0, {}, -1.0]", -wall - dx));
        ov.push(format!("fixed_regions.0.max=[1.0, {}, 1.0]", wall + dx));
    }
    ov
}

/// V1 — start-up Poiseuille flow (SPEC §7.1).
fn poiseuille(ctx: &Ctx) -> Result<Vec<CaseResult>, ValidationError> {
    let started = Instant::now();
    let (ny, nx) = if ctx.quick { (40, 20) } else { (100, 50) };
    let sc = load(POISEUILLE, "poiseuille.ron", &channel_overrides(ny, nx, false))?;
    let res = format!("{ny} rows x {nx} columns");
    let h = 0.01;
    let dx = 2.0 * h / ny as f64;
    let liquid = sc.liquid.as_ref().ok_or_else(|| missing("liquid"))?;
    let (rho0, eta, f) = (liquid.density, liquid.viscosity, sc.gravity[0]);
    let vel = h * h * rho0 * f / (3.0 * eta);
    let time = rho0 * h * h / eta;
    let instants = [0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 3.0];
    let mut sim = Simulation::new(&sc, ctx.backend)?;
    let origin = sim.params().origin;
    let mut inv = Invariants::default();
    let mut centre_series = Vec::new();
    let mut profiles: Vec<Series> = Vec::new();
    let (mut worst_centre, mut worst_rms, mut worst_nl, mut leaked) = (0.0f64, 0.0f64, 0.0f64, 0usize);
    let mut next = 0usize;
    let mut next_sample = 0.0;
    let bar = ctx.progress.then(crate::output::progress_bar);
    while next < instants.len() {
        let t = advance_to(&mut sim, f64::min(next_sample, instants[next]) * time)?;
        let ts = t / time;
        if ts >= next_sample || ts >= instants[next] {
            let s = sim.read_state()?;
            let (mut c_sum, mut c_ref, mut c_n) = (0.0, 0.0, 0usize);
            let (mut sq, mut n_l_dev) = (0.0, 0.0f64);
            for i in 0..s.liquid.len() {
                let y = s.liquid.pos[i].y as f64 + origin[1];
                let vx = s.liquid.vel[i].x as f64;
                let va = vel * poiseuille_startup(y / h, ts);
                sq += (vx - va) * (vx - va);
                if y.abs() < dx {
                    c_sum += vx;
                    c_ref += va;
                    c_n += 1;
                }
                n_l_dev = n_l_dev.max((s.liquid.n_l[i] as f64 - 1.0).abs());
                if y.abs() > h + 0.5 * dx {
                    leaked += 1;
                }
            }
            worst_nl = worst_nl.max(n_l_dev);
            inv.check(&sim, &s);
            let centre = c_sum / c_n.max(1) as f64;
            centre_series.push((ts, centre / vel));
            next_sample = ts + 0.01;
            if ts >= instants[next] {
                let ce = (centre - c_ref / c_n.max(1) as f64).abs() / (1.5 * vel);
                let rms = (sq / s.liquid.len() as f64).sqrt() / (1.5 * vel);
                worst_centre = worst_centre.max(ce);
                worst_rms = worst_rms.max(rms);
                log::info!("poiseuille t* = {ts:.3}: centreline error {ce:.4}, RMS {rms:.4}");
                let mut rows: std::collections::BTreeMap<i64, (f64, usize)> = Default::default();
                for i in 0..s.liquid.len() {
                    let y = s.liquid.pos[i].y as f64 + origin[1];
                    let e = rows.entry((y / dx).round() as i64).or_insert((0.0, 0));
                    e.0 += s.liquid.vel[i].x as f64;
                    e.1 += 1;
                }
                profiles.push(Series {
                    label: format!("SPH t*={}", instants[next]),
                    points: rows.iter().map(|(k, (v, n))| (*k as f64 * dx / h, v / *n as f64 / vel)).collect(),
                    markers: true,
                });
                profiles.push(Series {
                    label: format!("exact t*={}", instants[next]),
                    points: (0..=100)
                        .map(|k| {
                            let y = -1.0 + 0.02 * k as f64;
                            (y, poiseuille_startup(y, ts))
                        })
                        .collect(),
                    markers: false,
                });
                next += 1;
            }
            if let Some(b) = &bar {
                b.set_position((ts / 3.0 * 1000.0) as u64);
            }
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let exact: Vec<(f64, f64)> =
        (0..=300).map(|k| (k as f64 * 0.01, poiseuille_startup(dx / 2.0 / h, k as f64 * 0.01))).collect();
    plot(
        ctx,
        "poiseuille_centreline.png",
        &Chart {
            title: "Start-up Poiseuille: centreline velocity (thesis Fig. 4.1)",
            x_label: "t* = t eta / (rho H^2)",
            y_label: "v / V",
            series: vec![
                Series { label: "SPH".into(), points: centre_series, markers: true },
                Series { label: "series (4.1)".into(), points: exact, markers: false },
            ],
        },
    )?;
    plot(
        ctx,
        "poiseuille_profiles.png",
        &Chart {
            title: "Start-up Poiseuille: profiles (thesis Fig. 4.2)",
            x_label: "y / H",
            y_label: "v / V",
            series: profiles,
        },
    )?;
    let wall = started.elapsed().as_secs_f64();
    let tol = if ctx.quick { 0.05 } else { 0.03 };
    Ok(vec![
        at_most("poiseuille", &res, "centreline_error_max", worst_centre, tol, wall),
        at_most("poiseuille", &res, "profile_rms_error_max", worst_rms, tol, wall),
        at_most("poiseuille", &res, "max_abs_nl_minus_1", worst_nl, 0.02, wall),
        at_most("poiseuille", &res, "leaked_particles", leaked as f64, 0.0, wall),
        inv.result("poiseuille", &res, wall),
    ])
}

/// Advances (one chunk: up to `ADVANCE_CHUNK` steps, one GPU batch) towards the first step at or after
/// `target`, stopping a hair (10⁻⁹ relative) early so that a caller re-checking its own exact sample
/// condition on the returned clock sees the same step as with single steps; steps once if the clock is
/// already there.
pub(crate) fn advance_to(sim: &mut Simulation, target: f64) -> Result<f64, SimError> {
    let t_stop = target - 1e-9 * target.abs();
    if t_stop > sim.time() {
        sim.advance(crate::sim::ADVANCE_CHUNK, t_stop)?;
    } else {
        sim.advance(1, f64::INFINITY)?;
    }
    Ok(sim.time())
}

/// A log line per sample of a long case: the steps since the last sample, their mean Δt, the criterion
/// that limited most of them and the wall time they took — how a run's pace changes as it goes (e.g.
/// when a blade starts cutting).
pub(crate) struct Pace {
    stats: crate::sim::RunStats,
    t: f64,
    wall: std::time::Instant,
}

impl Pace {
    pub(crate) fn new(sim: &Simulation) -> Self {
        Self { stats: sim.stats().clone(), t: sim.time(), wall: std::time::Instant::now() }
    }

    /// Logs the pace since the last call (or `new`) and starts the next interval.
    pub(crate) fn log(&mut self, name: &str, sim: &Simulation) {
        let now = sim.stats();
        let steps = now.steps.saturating_sub(self.stats.steps);
        let limit = now
            .dt_limited_by
            .iter()
            .map(|(k, n)| (k, n.saturating_sub(self.stats.dt_limited_by.get(k).copied().unwrap_or(0))))
            .max_by_key(|(_, n)| *n)
            .map_or("-", |(k, _)| k.as_str());
        log::info!(
            "{name}: t = {:.3} s, {steps} steps since t = {:.3} s (mean dt {:.2e} s, mostly limited by {limit}), {:.1} s wall",
            sim.time(),
            self.t,
            (sim.time() - self.t) / steps.max(1) as f64,
            self.wall.elapsed().as_secs_f64()
        );
        *self = Self::new(sim);
    }
}

fn missing(what: &str) -> ValidationError {
    ValidationError::Io { path: "(embedded scenario)".into(), message: format!("the scenario has no {what}") }
}

/// Steady Brinkman run: returns (centreline relative error, RMS profile error / u(0), row profile).
struct BrinkmanOutcome {
    centre_err: f64,
    rms_err: f64,
    u_centre: f64,
    u_ref: f64,
    profile: Vec<(f64, f64)>,
    reference: Vec<(f64, f64)>,
    invariants: Invariants,
}

fn brinkman_run(
    ctx: &Ctx,
    ny: usize,
    duration: f64,
    window: f64,
    extra: &[String],
) -> Result<BrinkmanOutcome, ValidationError> {
    let nx = (ny / 2).max(10);
    let mut ov = channel_overrides(ny, nx, true);
    ov.push(format!("duration={duration}"));
    ov.extend_from_slice(extra);
    let sc = load(BRINKMAN, "brinkman.ron", &ov)?;
    let h = 0.01;
    let dx = 2.0 * h / ny as f64;
    let liquid = sc.liquid.as_ref().ok_or_else(|| missing("liquid"))?;
    let solid = sc.solid.as_ref().ok_or_else(|| missing("solid"))?;
    let (rho0, eta, f, kbar) = (liquid.density, liquid.viscosity, sc.gravity[0], solid.friction);
    let (n_l, n_s) = (0.5, 0.5);
    let k = (1.0 - n_s) * kbar;
    let mut sim = Simulation::new(&sc, ctx.backend)?;
    let origin = sim.params().origin;
    let mut inv = Invariants::default();
    let mut rows: std::collections::BTreeMap<i64, (f64, usize)> = Default::default();
    let mut next_sample = 0.0;
    let t0 = duration - window;
    while sim.time() < duration {
        let t = advance_to(&mut sim, f64::min(next_sample, duration))?;
        if t >= next_sample {
            next_sample = t + duration / 100.0;
            let s = sim.read_state()?;
            inv.check(&sim, &s);
            if t >= t0 {
                for i in 0..s.liquid.len() {
                    let y = s.liquid.pos[i].y as f64 + origin[1];
                    let e = rows.entry(((y / dx) - 0.5).round() as i64).or_insert((0.0, 0));
                    e.0 += s.liquid.vel[i].x as f64;
                    e.1 += 1;
                }
            }
        }
    }
    let u_at = |y: f64| brinkman_steady(y, h, n_l, rho0, f, k, eta);
    let profile: Vec<(f64, f64)> = rows.iter().map(|(r, (v, n))| ((*r as f64 + 0.5) * dx, v / *n as f64)).collect();
    let u_ref = u_at(0.5 * dx);
    let centre: Vec<f64> = profile.iter().filter(|(y, _)| y.abs() < dx).map(|p| p.1).collect();
    let u_centre = centre.iter().sum::<f64>() / centre.len().max(1) as f64;
    let rms = (profile.iter().map(|(y, u)| (u - u_at(*y)).powi(2)).sum::<f64>() / profile.len().max(1) as f64).sqrt();
    let reference = (0..=100)
        .map(|k| {
            let y = -h + 0.02 * h * k as f64;
            (y / h, u_at(y))
        })
        .collect();
    Ok(BrinkmanOutcome {
        centre_err: (u_centre - u_ref).abs() / u_ref.abs().max(1e-30),
        rms_err: rms / u_at(0.0).abs().max(1e-30),
        u_centre,
        u_ref,
        profile: profile.iter().map(|(y, u)| (y / h, *u)).collect(),
        reference,
        invariants: inv,
    })
}

/// V3 — Brinkman flow through a static porous medium (SPEC §7.3) and its frictionless control.
fn brinkman(ctx: &Ctx) -> Result<Vec<CaseResult>, ValidationError> {
    let started = Instant::now();
    let ny = if ctx.quick { 40 } else { 100 };
    let res = format!("{ny} rows x {} columns", ny / 2);
    let b = brinkman_run(ctx, ny, 0.5, 0.1, &[])?;
    let control = brinkman_run(ctx, ny, 0.5, 0.1, &["solid.friction=0.0".to_string()])?;
    log::info!(
        "brinkman: u(0) = {:.5} vs {:.5}; control {:.5} vs {:.5}",
        b.u_centre,
        b.u_ref,
        control.u_centre,
        control.u_ref
    );
    plot(
        ctx,
        "brinkman_profile.png",
        &Chart {
            title: "Brinkman flow through a static porous medium (thesis Fig. 4.4)",
            x_label: "y / H",
            y_label: "u [m/s]",
            series: vec![
                Series { label: "SPH, K* = 4".into(), points: b.profile.clone(), markers: true },
                Series { label: "Brinkman".into(), points: b.reference.clone(), markers: false },
                Series { label: "SPH, K = 0".into(), points: control.profile.clone(), markers: true },
                Series { label: "Poiseuille".into(), points: control.reference.clone(), markers: false },
            ],
        },
    )?;
    let wall = started.elapsed().as_secs_f64();
    let tol = if ctx.quick { 0.04 } else { 0.02 };
    Ok(vec![
        at_most("brinkman", &res, "centreline_rel_error", b.centre_err, tol, wall),
        at_most("brinkman", &res, "profile_rms_error", b.rms_err, 0.03, wall),
        at_most("brinkman", &res, "control_kbar0_centreline_rel_error", control.centre_err, 0.04, wall),
        b.invariants.result("brinkman", &res, wall),
    ])
}

/// V4 — convergence of the Brinkman error with spacing (SPEC §7.4): δx relative to the channel width
/// 2H, i.e. δx = 1/N_y [D-33]. Acceptance (i) monotone within 0.005 per refinement, (ii) e(0.05) −
/// e(0.0125) > 0 unless both are below 0.005, (iii) the finest ≤ 0.02; (iv) reported: the error at
/// each spacing, the log–log slope fitted between δx = 0.05 and 0.02, and the saturation level (the
/// mean error below δx = 0.02).
fn convergence(ctx: &Ctx) -> Result<Vec<CaseResult>, ValidationError> {
    let started = Instant::now();
    let (rows, duration, window): (&[usize], f64, f64) =
        if ctx.quick { (&[20, 40, 80], 0.3, 0.05) } else { (&[20, 25, 40, 50, 80, 100], 0.5, 0.1) };
    let mut errs = Vec::new();
    let mut inv_bad = 0usize;
    for &ny in rows {
        let b = brinkman_run(ctx, ny, duration, window, &[])?;
        log::info!("convergence: {ny} rows: error {:.5}", b.centre_err);
        inv_bad += b.invariants.violations.len();
        errs.push((1.0 / ny as f64, b.centre_err));
    }
    plot(
        ctx,
        "convergence.png",
        &Chart {
            title: "Brinkman centreline error vs spacing (thesis Fig. 4.5)",
            x_label: "dx / (2H)",
            y_label: "relative error",
            series: vec![Series { label: "SPH".into(), points: errs.clone(), markers: true }],
        },
    )?;
    let stats = ConvergenceStats::of(&errs);
    let res = format!("{} spacings, {:?} rows", rows.len(), rows);
    let wall = started.elapsed().as_secs_f64();
    let mut out = vec![
        at_most("convergence", &res, "max_error_increase", stats.worst_increase, 0.005, wall),
        row("convergence", &res, "error_0.05_minus_error_0.0125", stats.drop, 0.0, stats.drop_ok, wall),
        at_most("convergence", &res, "finest_error", stats.finest, 0.02, wall),
        at_most("convergence", &res, "invariant_violations", inv_bad as f64, 0.0, wall),
    ];
    for (&ny, &(_, e)) in rows.iter().zip(&errs) {
        out.push(reported("convergence", &res, &format!("error_{ny}_rows"), e, wall));
    }
    out.push(reported("convergence", &res, "loglog_slope_0.05_to_0.02", stats.slope, wall));
    out.push(reported("convergence", &res, "saturation_error_below_0.02", stats.saturation, wall));
    Ok(out)
}

/// SPEC §7.4's figures of a convergence sequence of (δx, e), coarse to fine.
#[derive(Debug, PartialEq)]
struct ConvergenceStats {
    /// Largest increase of e from one spacing to the next finer (0 when it never rises).
    worst_increase: f64,
    /// e(0.05) − e(0.0125) (NaN when either spacing is missing).
    drop: f64,
    /// (ii): the drop is positive, or both errors are below 0.005.
    drop_ok: bool,
    /// e at the finest spacing.
    finest: f64,
    /// Least-squares slope of ln e against ln δx over δx ∈ [0.02, 0.05] (NaN with fewer than two points).
    slope: f64,
    /// Mean e over δx < 0.02 (NaN when there is none).
    saturation: f64,
}

impl ConvergenceStats {
    fn of(errs: &[(f64, f64)]) -> ConvergenceStats {
        let worst_increase = errs.windows(2).map(|w| w[1].1 - w[0].1).fold(0.0f64, f64::max);
        let at = |dx: f64| errs.iter().find(|(d, _)| (d - dx).abs() < 1e-9).map(|e| e.1);
        let (drop, drop_ok) = match (at(0.05), at(0.0125)) {
            (Some(c), Some(f)) => (c - f, c - f > 0.0 || (c < 0.005 && f < 0.005)),
            _ => (f64::NAN, false),
        };
        let fit: Vec<(f64, f64)> = errs
            .iter()
            .filter(|(d, e)| *d >= 0.02 - 1e-9 && *d <= 0.05 + 1e-9 && *e > 0.0)
            .map(|(d, e)| (d.ln(), e.ln()))
            .collect();
        let slope = if fit.len() >= 2 {
            let n = fit.len() as f64;
            let (mx, my) = (fit.iter().map(|p| p.0).sum::<f64>() / n, fit.iter().map(|p| p.1).sum::<f64>() / n);
            let sxy: f64 = fit.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
            let sxx: f64 = fit.iter().map(|p| (p.0 - mx).powi(2)).sum();
            sxy / sxx
        } else {
            f64::NAN
        };
        let fine: Vec<f64> = errs.iter().filter(|(d, _)| *d < 0.02 - 1e-9).map(|e| e.1).collect();
        let saturation = if fine.is_empty() { f64::NAN } else { fine.iter().sum::<f64>() / fine.len() as f64 };
        ConvergenceStats {
            worst_increase,
            drop,
            drop_ok,
            finest: errs.last().map(|e| e.1).unwrap_or(f64::NAN),
            slope,
            saturation,
        }
    }
}

/// Hydrostatic column: bottom pressure vs ρgh after settling, stable over 10⁴ steps, no leakage.
fn hydrostatic(ctx: &Ctx) -> Result<Vec<CaseResult>, ValidationError> {
    let started = Instant::now();
    let ov: Vec<String> = if ctx.quick {
        Vec::new()
    } else {
        vec![
            "numerics.dx_liquid=0.00125".into(),
            "boundaries.0.spacing=0.00125".into(),
            "boundaries.1.spacing=0.00125".into(),
            "boundaries.2.spacing=0.00125".into(),
        ]
    };
    let sc = load(HYDROSTATIC, "hydrostatic.ron", &ov)?;
    let dx = sc.numerics.dx_liquid.unwrap_or(0.0025);
    let res = format!("dx = {dx} m");
    let liquid = sc.liquid.as_ref().ok_or_else(|| missing("liquid"))?;
    let rho0 = liquid.density;
    let g = -sc.gravity[1];
    let (fill, half_w) = (0.1, 0.05);
    let mut sim = Simulation::new(&sc, ctx.backend)?;
    let origin = sim.params().origin;
    super::relaxation::relax_cached(ctx.relax, &sc, &mut sim)?;
    let s0 = sim.read_state()?;
    // Bottom row, away from the side walls (x within the central half).
    let bottom: Vec<usize> = (0..s0.liquid.len())
        .filter(|&i| {
            let x = s0.liquid.pos[i].x as f64 + origin[0];
            let y = s0.liquid.pos[i].y as f64 + origin[1];
            y < dx && x.abs() < 0.5 * half_w
        })
        .collect();
    let expect = rho0 * g * (fill - 0.5 * dx);
    let mut inv = Invariants::default();
    let mut samples = Vec::new();
    let mut leaked = 0usize;
    let steps = 10_000;
    for _ in 0..steps / 20 {
        // 20 steps per sample, in one chunk (one GPU batch).
        sim.advance(20, f64::INFINITY)?;
        {
            let s = sim.read_state()?;
            inv.check(&sim, &s);
            let p = bottom.iter().map(|&i| s.liquid.p[i] as f64).sum::<f64>() / bottom.len().max(1) as f64;
            samples.push((s.t, p / expect));
            leaked = leaked.max(
                s.liquid
                    .pos
                    .iter()
                    .filter(|x| {
                        (x.y as f64 + origin[1]) < -0.5 * dx || (x.x as f64 + origin[0]).abs() > half_w + 0.5 * dx
                    })
                    .count(),
            );
        }
    }
    let mean = samples.iter().map(|s| s.1).sum::<f64>() / samples.len().max(1) as f64;
    let n5 = (samples.len() / 5).max(1);
    let first = samples[..n5].iter().map(|s| s.1).sum::<f64>() / n5 as f64;
    let last = samples[samples.len() - n5..].iter().map(|s| s.1).sum::<f64>() / n5 as f64;
    plot(
        ctx,
        "hydrostatic.png",
        &Chart {
            title: "Hydrostatic column: bottom pressure / rho g h",
            x_label: "t [s] (after relaxation)",
            y_label: "p / (rho g h)",
            series: vec![
                Series { label: "SPH bottom row".into(), points: samples.clone(), markers: true },
                Series {
                    label: "rho g h".into(),
                    points: vec![
                        (samples.first().map(|s| s.0).unwrap_or(0.0), 1.0),
                        (samples.last().map(|s| s.0).unwrap_or(1.0), 1.0),
                    ],
                    markers: false,
                },
            ],
        },
    )?;
    let wall = started.elapsed().as_secs_f64();
    Ok(vec![
        at_most("hydrostatic", &res, "bottom_pressure_rel_error", (mean - 1.0).abs(), 0.02, wall),
        at_most("hydrostatic", &res, "pressure_drift_over_1e4_steps", (last - first).abs(), 0.02, wall),
        at_most("hydrostatic", &res, "particles_through_walls", leaked as f64, 0.0, wall),
        inv.result("hydrostatic", &res, wall),
    ])
}

/// V2 — cantilever free vibration (SPEC §7.2): the thesis beam (3-D) in the standard run, a 2-D
/// plane-strain beam with 7 particles across in `--quick`.
fn cantilever(ctx: &Ctx) -> Result<Vec<CaseResult>, ValidationError> {
    let started = Instant::now();
    let (text, file) = if ctx.quick { (CANTILEVER_2D, "cantilever_2d.ron") } else { (CANTILEVER, "cantilever.ron") };
    let sc = load(text, file, &[])?;
    let solid = sc.solid.as_ref().ok_or_else(|| missing("solid"))?;
    let dx = sc.numerics.dx_solid.unwrap_or(0.0);
    let (root, length, amp) = match sc.particles.first() {
        Some(crate::scenario::Generator::Box {
            velocity: Some(crate::scenario::InitialVelocity::CantileverMode { root, length, amplitude, .. }),
            ..
        }) => (*root, *length, *amplitude),
        _ => return Err(missing("cantilever-mode generator")),
    };
    let mut sim = Simulation::new(&sc, ctx.backend)?;
    let origin = sim.params().origin;
    let s0 = sim.read_state()?;
    let flags = &s0.solid_extra.flags;
    let free: Vec<usize> =
        (0..s0.solid.len()).filter(|&i| flags[i] & crate::scenario::SolidFlags::KINEMATIC == 0).collect();
    let tip: Vec<usize> = free
        .iter()
        .copied()
        .filter(|&i| (s0.solid.pos[i].x as f64 + origin[0] - (root + length)).abs() < 0.5 * dx)
        .collect();
    let across = free.iter().filter(|&&i| (s0.solid.pos[i].x as f64 + origin[0] - root).abs() < 0.5 * dx).count();
    let three_d = sc.dimensions == 3;
    let n_across = if three_d { (across as f64).sqrt().round() as usize } else { across };
    let a = (n_across as f64 - 1.0) * dx;
    let mu: f64 = free.iter().map(|&i| s0.solid.mass[i] as f64).sum::<f64>() / length;
    let g_mod = 2.0 * (solid.c10 + solid.c01);
    let (e, nu) = young_poisson(solid.k_s, g_mod);
    let (e_eff, inertia) = if three_d { (e, a.powi(4) / 12.0) } else { (e / (1.0 - nu * nu), a.powi(3) / 12.0) };
    let omega_ref = cantilever_omega1(e_eff, inertia, mu, length);
    let y0 = tip.iter().map(|&i| s0.solid.pos[i].y as f64).sum::<f64>() / tip.len().max(1) as f64;
    let mut series = Vec::new();
    let mut max_j_dev = 0.0f64;
    let bar = ctx.progress.then(crate::output::progress_bar);
    let mut next_sample = 0.0;
    let sample_dt = 2.0 * std::f64::consts::PI / omega_ref / 200.0;
    let mut inv = Invariants::default();
    while sim.time() < sc.duration {
        let t = advance_to(&mut sim, f64::min(next_sample, sc.duration))?;
        if t >= next_sample {
            next_sample = t + sample_dt;
            let s = sim.read_state()?;
            let w = tip.iter().map(|&i| s.solid.pos[i].y as f64).sum::<f64>() / tip.len().max(1) as f64 - y0;
            series.push((s.t, w));
            for &i in &free {
                max_j_dev = max_j_dev.max((s.solid_extra.def_grad[i].determinant() as f64 - 1.0).abs());
            }
            if series.len() % 20 == 0 {
                inv.check(&sim, &s);
            }
            if let Some(b) = &bar {
                b.set_position((t / sc.duration * 1000.0) as u64);
            }
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let fin = sim.read_state()?;
    // Zero crossings (linear interpolation), skipping the start at w = 0.
    let mut crossings = Vec::new();
    for w in series.windows(2) {
        let ((t0, a0), (t1, a1)) = (w[0], w[1]);
        if t0 > 0.0 && a0 != 0.0 && a0.signum() != a1.signum() {
            crossings.push(t0 + (t1 - t0) * a0.abs() / (a0.abs() + a1.abs()));
        }
    }
    let omega = if crossings.len() >= 2 {
        let half = (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64;
        std::f64::consts::PI / half
    } else {
        f64::NAN
    };
    // Peak amplitudes per half cycle.
    let mut peaks = Vec::new();
    let mut seg_start = 0.0;
    for &c in crossings.iter().chain(std::iter::once(&f64::INFINITY)) {
        let seg: Vec<f64> = series.iter().filter(|(t, _)| *t > seg_start && *t < c).map(|p| p.1.abs()).collect();
        if c.is_finite() && !seg.is_empty() {
            peaks.push(seg.iter().cloned().fold(0.0, f64::max));
        }
        seg_start = c;
    }
    let decay = if peaks.len() >= 2 { 1.0 - peaks[peaks.len() - 1] / peaks[0] } else { f64::NAN };
    log::info!("cantilever: omega {omega:.4} vs {omega_ref:.4}, peaks {peaks:?}");
    plot(
        ctx,
        "cantilever_tip.png",
        &Chart {
            title: "Cantilever free vibration: tip deflection (thesis Fig. 4.3)",
            x_label: "t [s]",
            y_label: "w [m]",
            series: vec![
                Series { label: "SPH tip".into(), points: series.clone(), markers: false },
                Series {
                    label: format!("E-B w1 = {omega_ref:.3} rad/s"),
                    points: series.iter().map(|(t, _)| (*t, amp / omega_ref * (omega_ref * t).sin())).collect(),
                    markers: false,
                },
            ],
        },
    )?;
    let res = if three_d {
        format!("{} particles, {n_across}x{n_across} across", fin.solid.len())
    } else {
        format!("2-D plane strain, {} particles, {n_across} across", fin.solid.len())
    };
    let wall = started.elapsed().as_secs_f64();
    let tol = if ctx.quick { 0.05 } else { 0.02 };
    // The issue asserts the amplitude decay on the thesis-size beam only; the reduced beam reports it.
    let decay_row = if ctx.quick {
        reported("cantilever", &res, "amplitude_decay", decay, wall)
    } else {
        at_most("cantilever", &res, "amplitude_decay_3_periods", decay, 0.10, wall)
    };
    let mut rows = vec![
        at_most("cantilever", &res, "omega_rel_error", (omega / omega_ref - 1.0).abs(), tol, wall),
        decay_row,
        at_most("cantilever", &res, "max_abs_J_minus_1", max_j_dev, 0.05, wall),
        at_most("cantilever", &res, "broken_bonds", fin.broken_bonds() as f64, 0.0, wall),
        inv.result("cantilever", &res, wall),
    ];
    if !ctx.quick {
        let first = peaks.first().copied().unwrap_or(f64::NAN);
        rows.push(at_most(
            "cantilever",
            &res,
            "first_peak_rel_error",
            (first / (amp / omega_ref) - 1.0).abs(),
            0.25,
            wall,
        ));
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::ConvergenceStats;

    /// SPEC §7.4's figures on sequences with known answers: a power law e = 0.4 δx² down to δx = 0.02,
    /// then a floor (slope 2 over [0.02, 0.05], the floor as saturation); a rise by 0.003 and one by
    /// 0.01; rule (ii) with both ends below 0.005.
    #[test]
    fn convergence_figures_of_known_sequences() {
        let rows = [20.0, 25.0, 40.0, 50.0, 80.0, 100.0];
        let e = |dx: f64| if dx >= 0.02 - 1e-12 { 0.4 * dx * dx } else { 0.4 * 0.02f64.powi(2) };
        let errs: Vec<(f64, f64)> = rows.iter().map(|n| (1.0 / n, e(1.0 / n))).collect();
        let s = ConvergenceStats::of(&errs);
        assert!((s.slope - 2.0).abs() < 1e-9, "slope {}", s.slope);
        assert!((s.saturation - 1.6e-4).abs() < 1e-12, "saturation {}", s.saturation);
        assert_eq!(s.worst_increase, 0.0);
        assert!((s.drop - (1e-3 - 1.6e-4)).abs() < 1e-12 && s.drop_ok);
        assert_eq!(s.finest, 1.6e-4);

        let bumpy = [(0.05, 0.020), (0.025, 0.023), (0.0125, 0.013)];
        let s = ConvergenceStats::of(&bumpy);
        assert!((s.worst_increase - 0.003).abs() < 1e-12 && s.drop_ok);
        let rising = [(0.05, 0.010), (0.025, 0.015), (0.0125, 0.020)];
        let s = ConvergenceStats::of(&rising);
        assert!((s.worst_increase - 0.005).abs() < 1e-12 && !s.drop_ok);
        let tiny = [(0.05, 0.003), (0.025, 0.0035), (0.0125, 0.004)];
        assert!(ConvergenceStats::of(&tiny).drop_ok, "both below 0.005");
        assert!(ConvergenceStats::of(&[(0.05, 0.01)]).slope.is_nan());
    }
}
