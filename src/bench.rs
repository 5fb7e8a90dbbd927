//! `perfuse bench`: particle-steps per second of the whole step (grid included) for each back-end on a
//! perfused block at a list of sizes, time per pass, memory per particle and the fitted slope of cost
//! vs N; or the same for any scenario, with its real-time factor and dt-limiting criterion — the figure
//! that decides whether a surgeon can work interactively.

use crate::replay::format::ReplayError;
use crate::replay::session::{HASH_EVERY, KEYFRAME_EVERY, RecordedSimulation, Recorder};
use crate::scenario::{Scenario, ScenarioError};
use crate::sim::{BackendKind, SimError, Simulation};
use serde::Serialize;
use std::collections::BTreeMap;
use std::time::Instant;

/// One measured configuration (one row of `--json`).
#[derive(Clone, Debug, Serialize)]
pub struct BenchRow {
    pub backend: String,
    pub adapter: String,
    pub scenario: String,
    /// Liquid + solid particles (boundary particles excluded).
    pub particles: usize,
    pub boundary_particles: usize,
    pub steps: u64,
    pub wall_s: f64,
    pub ps_per_s: f64,
    pub ms_per_step: f64,
    /// Milliseconds per step spent in each pass family.
    pub pass_ms_per_step: BTreeMap<String, f64>,
    pub bytes_per_particle: f64,
    pub dt_mean_s: f64,
    /// Simulated seconds per wall second.
    pub real_time_factor: f64,
    /// The criterion of (2.70) that limited Δt most often.
    pub dt_limited_by: String,
    /// With `--record`: what recording the session cost.
    pub recording: Option<RecordCost>,
    /// GPU: host time of the per-batch error scopes (push + pop) per batch \[µs\], and the batches it
    /// is the mean of (the warm-up batch included).
    pub error_scope_us_per_batch: Option<f64>,
    pub batches: Option<u64>,
}

/// What recording a session costs (`perfuse bench --record`): the run is recorded as the viewer
/// records (a keyframe at the start, then one every [`KEYFRAME_EVERY`] of stepping, a state hash
/// every [`HASH_EVERY`]) and compared with a run without recording.
#[derive(Clone, Debug, Default, Serialize)]
pub struct RecordCost {
    pub file_bytes: u64,
    pub keyframes: u64,
    /// Mean wall time of one keyframe: readback, encoding, compression, write \[ms\].
    pub keyframe_ms: f64,
    /// Mean size of one keyframe on disk \[bytes\].
    pub keyframe_bytes: f64,
    pub hashes: u64,
    /// Mean wall time of one state hash (a readback) \[ms\].
    pub hash_ms: f64,
    /// 1 − PS/s(recorded) / PS/s(not recorded), runs of the same length [%] (noisy on short runs).
    pub overhead_measured_pct: f64,
    /// Steady state of the viewer's policy: keyframe_ms per KEYFRAME_EVERY plus hash_ms per
    /// HASH_EVERY of stepping [%].
    pub overhead_policy_pct: f64,
    /// Recording size per simulated second with the viewer's policy at this speed [bytes/s].
    pub bytes_per_simulated_s: f64,
}

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BenchError {
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error(transparent)]
    Sim(#[from] SimError),
    #[error(transparent)]
    Record(#[from] ReplayError),
}

/// The §7.5 tissue specimen (perfused cube, 5 cm, on a plate, gravity) with about `n` particles
/// (half solid, half liquid, on interpenetrating lattices of one spacing).
pub fn perfused_block(n: usize) -> Result<Scenario, ScenarioError> {
    let per_phase = (n as f64 / 2.0).max(8.0);
    let k = per_phase.cbrt().round().max(2.0);
    let side = 0.05;
    let dx = side / k;
    let h = side / 2.0;
    let text = format!(
        r#"Scenario(
    name: "bench_block_{n}",
    description: "perfused tissue block on a plate (SPEC 7.5 materials) for benchmarking",
    dimensions: 3,
    domain: Domain(min: (-0.06, -0.06, -0.02), max: (0.06, 0.06, 0.08)),
    gravity: (0.0, 0.0, -9.81),
    liquid: Some(Liquid(density: 1000.0, viscosity: 0.35, stiffness: Some(1.0e5))),
    solid: Some(Solid(density: 1000.0, c10: 1.0e5, c01: 400.0, k_s: 1.0e5, n_sat: 0.6, k_sat: 1.0e5, friction: 1.0e6)),
    numerics: Numerics(dx_liquid: Some({dx}), dx_solid: Some({dx}), h_over_dx: 1.3),
    particles: [ PerfusedBlock(min: (-{h}, -{h}, 0.0), max: ({h}, {h}, {side}), solid_fraction: 0.6, liquid_fraction: 0.4) ],
    boundaries: [ Boundary(name: "plate", shape: Box(min: (-0.055, -0.055, -{plate}), max: (0.055, 0.055, 0.0))) ],
    duration: 1.0,
)"#,
        plate = 3.0 * dx
    );
    Scenario::from_str_named(&text, "(bench block)")
}

/// Steps `sc` on `backend` for at least `min_wall_s` seconds (after one warm-up step) and at least
/// `min_steps` steps, at most `max_steps`, with `Simulation::advance` (GPU: batches, no per-step
/// readback).
pub fn measure(
    sc: &Scenario,
    backend: BackendKind,
    min_wall_s: f64,
    min_steps: u64,
    max_steps: u64,
) -> Result<BenchRow, BenchError> {
    measure_with(sc, backend, min_wall_s, min_steps, max_steps, None, Setup::default())
}

/// How [`measure_with`] sets the measured simulation up.
#[derive(Clone, Copy, Debug, Default)]
pub struct Setup {
    /// Generate the liquid in a random storage order ([`shuffle_liquid`]).
    pub shuffled_liquid: bool,
    /// GPU: time the passes per entry point instead of per family.
    pub entry_points: bool,
}

/// Puts the generated liquid in a random storage order (a fixed xorshift permutation): the locality a
/// long mixing flow leaves behind, which `numerics.reorder_liquid` restores (`perfuse bench
/// --shuffle-liquid`). The particles get their ids in this order, so it is a relabelling, not a change
/// of the scene.
pub fn shuffle_liquid(g: &mut crate::scenario::GeneratedParticles) {
    let n = g.liquid.pos.len();
    let mut perm: Vec<usize> = (0..n).collect();
    let mut x = 0x9e37_79b9_7f4a_7c15u64;
    for i in (1..n).rev() {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        perm.swap(i, (x % (i as u64 + 1)) as usize);
    }
    let l = &mut g.liquid;
    l.pos = perm.iter().map(|&i| l.pos[i]).collect();
    l.vel = perm.iter().map(|&i| l.vel[i]).collect();
    l.mass = perm.iter().map(|&i| l.mass[i]).collect();
}

/// [`measure`], recording the run to `record` as the viewer does (see [`RecordCost`]; its
/// `overhead_measured_pct` is filled in by [`record_overhead`]), set up as `setup` says.
pub fn measure_with(
    sc: &Scenario,
    backend: BackendKind,
    min_wall_s: f64,
    min_steps: u64,
    max_steps: u64,
    record: Option<&std::path::Path>,
    setup: Setup,
) -> Result<BenchRow, BenchError> {
    let mut generated = crate::scenario::generate(sc);
    if setup.shuffled_liquid {
        shuffle_liquid(&mut generated);
    }
    let mut sim = Simulation::from_generated(sc, generated, backend)?;
    sim.time_entry_points(setup.entry_points);
    let mut rs = RecordedSimulation { sim, recorder: None };
    rs.sim.step()?; // warm-up: first-use allocations, shader compilation
    let mut cost = RecordCost::default();
    let before: BTreeMap<String, f64> = rs.sim.pass_times().into_iter().collect();
    let t_sim0 = rs.sim.time();
    let steps0 = rs.sim.stats().steps;
    let start = Instant::now();
    let (mut kf_wall, mut kf_bytes, mut hash_wall) = (0.0, 0u64, 0.0);
    let (mut last_kf, mut last_hash) = (Instant::now(), Instant::now());
    if let Some(path) = record {
        rs.recorder = Some(Recorder::create(path, sc, &rs.sim.backend_name(), "")?);
        timed_keyframe(&mut rs, &mut cost, &mut kf_wall, &mut kf_bytes)?;
    }
    let mut n = 0u64;
    while n < max_steps && (n < min_steps || start.elapsed().as_secs_f64() < min_wall_s) {
        // Chunks (one GPU batch each) sized from the time per step so far, so that the run ends near
        // `min_wall_s`: one step first, then at most what the remaining time allows.
        let elapsed = start.elapsed().as_secs_f64();
        let per_step = if n > 0 { elapsed / n as f64 } else { f64::INFINITY };
        let by_time = ((min_wall_s - elapsed) / per_step).ceil().max(0.0) as u64;
        let chunk = by_time.max(min_steps.saturating_sub(n)).clamp(1, u64::from(crate::sim::ADVANCE_CHUNK));
        let chunk = chunk.min(max_steps - n) as u32;
        n += rs.sim.advance(chunk, f64::INFINITY)?.steps;
        if rs.recorder.is_some() {
            if last_hash.elapsed() >= HASH_EVERY {
                let t = Instant::now();
                rs.checkpoint()?;
                (hash_wall, cost.hashes, last_hash) = (hash_wall + t.elapsed().as_secs_f64(), cost.hashes + 1, t);
            }
            if last_kf.elapsed() >= KEYFRAME_EVERY {
                last_kf = Instant::now();
                timed_keyframe(&mut rs, &mut cost, &mut kf_wall, &mut kf_bytes)?;
            }
        }
    }
    let wall = start.elapsed().as_secs_f64();
    let sim_time = rs.sim.time() - t_sim0;
    let recording = match rs.recorder.take() {
        Some(r) => {
            cost.file_bytes = r.finish()?;
            cost.keyframe_ms = 1e3 * kf_wall / cost.keyframes.max(1) as f64;
            cost.keyframe_bytes = kf_bytes as f64 / cost.keyframes.max(1) as f64;
            cost.hash_ms = if cost.hashes > 0 { 1e3 * hash_wall / cost.hashes as f64 } else { 0.0 };
            let kf_every = KEYFRAME_EVERY.as_secs_f64();
            let hash_every = HASH_EVERY.as_secs_f64();
            cost.overhead_policy_pct = 100.0 * (cost.keyframe_ms / 1e3 / kf_every + cost.hash_ms / 1e3 / hash_every);
            let rtf = sim_time / wall;
            // a state-hash chunk is 44 bytes on disk
            cost.bytes_per_simulated_s = (cost.keyframe_bytes / kf_every + 44.0 / hash_every) / rtf.max(1e-30);
            Some(cost)
        }
        None => None,
    };
    let mut sim = rs.sim;
    let state = sim.read_state()?;
    let particles = state.liquid.len() + state.solid.len();
    let mut pass = BTreeMap::new();
    for (k, v) in sim.pass_times() {
        let d = v - before.get(&k).copied().unwrap_or(0.0);
        pass.insert(k, 1e3 * d / n.max(1) as f64);
    }
    let stats = sim.stats();
    let limit = stats.dt_limited_by.iter().max_by_key(|(_, c)| **c).map(|(k, _)| k.clone()).unwrap_or_default();
    debug_assert_eq!(stats.steps - steps0, n);
    let scopes = sim.error_scope_cost();
    let backend_name = sim.backend_name();
    let (backend_short, adapter) = match backend_name.split_once(' ') {
        Some((a, b)) => (a.to_string(), b.trim_matches(|c| c == '(' || c == ')').to_string()),
        None => (backend_name.clone(), String::new()),
    };
    Ok(BenchRow {
        backend: backend_short,
        adapter,
        scenario: sc.name.clone(),
        particles,
        boundary_particles: state.boundary.pos.len(),
        steps: n,
        wall_s: wall,
        ps_per_s: particles as f64 * n as f64 / wall,
        ms_per_step: 1e3 * wall / n.max(1) as f64,
        pass_ms_per_step: pass,
        bytes_per_particle: sim.memory_bytes() as f64 / particles.max(1) as f64,
        dt_mean_s: sim_time / n.max(1) as f64,
        real_time_factor: sim_time / wall,
        dt_limited_by: limit,
        recording,
        error_scope_us_per_batch: scopes.map(|(s, b)| 1e6 * s / b.max(1) as f64),
        batches: scopes.map(|(_, b)| b),
    })
}

fn timed_keyframe(
    rs: &mut RecordedSimulation,
    cost: &mut RecordCost,
    wall: &mut f64,
    bytes: &mut u64,
) -> Result<(), BenchError> {
    let before = rs.recorder.as_ref().map_or(0, |r| r.bytes_written());
    let t = Instant::now();
    rs.keyframe(None)?;
    *wall += t.elapsed().as_secs_f64();
    *bytes += rs.recorder.as_ref().map_or(0, |r| r.bytes_written()) - before;
    cost.keyframes += 1;
    Ok(())
}

/// Measures `sc` without and with recording (to `file`, removed afterwards), each for `min_wall_s`
/// (the liquid generated in a random order when `shuffled_liquid`); returns the recorded row with its
/// measured overhead.
pub fn record_overhead(
    sc: &Scenario,
    backend: BackendKind,
    min_wall_s: f64,
    file: &std::path::Path,
    setup: Setup,
) -> Result<(BenchRow, BenchRow), BenchError> {
    let plain = measure_with(sc, backend, min_wall_s, 3, u64::MAX, None, setup)?;
    let mut rec = measure_with(sc, backend, min_wall_s, 3, u64::MAX, Some(file), setup)?;
    let _ = std::fs::remove_file(file);
    if let Some(c) = &mut rec.recording {
        c.overhead_measured_pct = 100.0 * (1.0 - rec.ps_per_s / plain.ps_per_s.max(1e-30));
    }
    Ok((plain, rec))
}

/// The `--record` columns: overhead, keyframe cost and size, recording bytes per simulated second.
pub fn record_table(rows: &[BenchRow]) -> String {
    let mut out = format!(
        "{:<8} {:>9} {:>12} {:>12} {:>11} {:>12} {:>9} {:>14} {:>12}\n",
        "backend",
        "particles",
        "overhead %",
        "policy %",
        "keyframe ms",
        "keyframe MB",
        "hash ms",
        "MB per sim s",
        "file MB"
    );
    for r in rows {
        let Some(c) = &r.recording else { continue };
        out.push_str(&format!(
            "{:<8} {:>9} {:>12.1} {:>12.2} {:>11.1} {:>12.2} {:>9.2} {:>14.1} {:>12.2}\n",
            r.backend,
            r.particles,
            c.overhead_measured_pct,
            c.overhead_policy_pct,
            c.keyframe_ms,
            c.keyframe_bytes / 1e6,
            c.hash_ms,
            c.bytes_per_simulated_s / 1e6,
            c.file_bytes as f64 / 1e6
        ));
    }
    out
}

/// Least-squares slope of log(time per step) against log(N) over rows of one back-end.
pub fn cost_slope(rows: &[&BenchRow]) -> Option<f64> {
    if rows.len() < 2 {
        return None;
    }
    let pts: Vec<(f64, f64)> = rows.iter().map(|r| ((r.particles as f64).ln(), r.ms_per_step.ln())).collect();
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

/// `text` cut to `width` characters for a table column, its end marked by an ellipsis where cut (an
/// adapter's name such as "llvmpipe (LLVM 15.0.6, 256 bits)" is longer than the column).
fn column(text: &str, width: usize) -> String {
    if text.chars().count() <= width {
        return text.to_string();
    }
    let mut cut: String = text.chars().take(width.saturating_sub(1)).collect();
    cut.push('…');
    cut
}

/// Formats rows as a plain-text table.
pub fn table(rows: &[BenchRow]) -> String {
    let mut out = format!(
        "{:<8} {:<28} {:>9} {:>6} {:>12} {:>10} {:>8} {:>10} {:>9}  passes (ms/step)\n",
        "backend", "adapter", "particles", "steps", "PS/s", "ms/step", "B/part", "RTF", "dt limit"
    );
    for r in rows {
        let passes: Vec<String> = r.pass_ms_per_step.iter().map(|(k, v)| format!("{k} {v:.2}")).collect();
        out.push_str(&format!(
            "{:<8} {:<28} {:>9} {:>6} {:>12.3e} {:>10.2} {:>8.0} {:>10.2e} {:>9}  {}\n",
            r.backend,
            column(&r.adapter, 28),
            r.particles,
            r.steps,
            r.ps_per_s,
            r.ms_per_step,
            r.bytes_per_particle,
            r.real_time_factor,
            r.dt_limited_by,
            passes.join(", ")
        ));
    }
    for r in rows {
        if let (Some(us), Some(b)) = (r.error_scope_us_per_batch, r.batches) {
            let steps_per_batch = r.steps as f64 / b.max(1) as f64;
            out.push_str(&format!(
                "{} {} at {}: GPU error scopes {us:.1} µs of host time per batch ({b} batches; {:.1e} of a batch's wall time)\n",
                r.backend,
                r.adapter,
                r.particles,
                us * 1e-3 / (r.ms_per_step * steps_per_batch.max(1.0)),
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::column;

    #[test]
    fn a_long_adapter_name_is_cut_with_an_ellipsis() {
        assert_eq!(column("rayon, 2 threads", 28), "rayon, 2 threads");
        let cut = column("llvmpipe (LLVM 15.0.6, 256 bits)", 28);
        assert_eq!(cut.chars().count(), 28);
        assert_eq!(cut, "llvmpipe (LLVM 15.0.6, 256 …");
    }
}
