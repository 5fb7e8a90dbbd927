//! The simulation thread of the viewer: it owns the [`Simulation`], steps it as fast as it can (in
//! batches sized to about 30 ms of wall time, so commands and publication stay responsive), and after
//! each batch writes the back set of the two render buffer sets and publishes it by swapping an
//! index (DESIGN §Double buffering). It never waits for a frame; the render thread never waits for
//! it. The viewer reaches it only through [`Control`] messages on a channel — the same
//! [`Command`]s a recording holds, plus run control.
//!
//! It runs in one of two modes. Live: the user's commands drive the simulation, optionally recorded
//! (`--record FILE` or the record button) with a keyframe at the start, at the end of the
//! relaxation and every [`KEYFRAME_EVERY`] of stepping. Replay (`perfuse replay FILE`): a
//! [`Player`] feeds the recorded commands, the timeline seeks through its keyframes, and take-over
//! turns the player's simulation into a live one, optionally recording a branch.

use crate::replay::format::Recording;
use crate::replay::relaxed_cache::RelaxedCache;
use crate::replay::session::{HASH_EVERY, KEYFRAME_EVERY, Player, RecordedSimulation, Recorder, recorded_scenario};
use crate::scenario::Scenario;
use crate::sim::frame::{FrameBuffers, FrameInfo};
use crate::sim::gpu::GpuContext;
use crate::sim::{Command, DtLimit, SimError, Simulation};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// Messages from the viewer to the simulation thread.
#[derive(Clone, Debug)]
pub enum Control {
    /// A simulation command (tool poses, gravity, …): applied before the next step.
    Sim(Command),
    Pause(bool),
    /// One step (while paused).
    Step,
    /// Rebuild the scenario from its start (relaxation included).
    Reset,
    /// Load another scenario (ends a replay).
    Load(Box<Scenario>),
    /// Start recording the live session to this file (`Some`), or finish the recording (`None`).
    Record(Option<std::path::PathBuf>),
    /// Replay: go to simulated time t \[s\] (nearest keyframe before it, then stepping).
    Seek(f64),
    /// Replay: go to step n (the timeline seeks by step: through a relaxation the clock runs from
    /// −duration to 0, so time alone does not place it).
    SeekStep(u64),
    /// Replay: playback speed as a fraction of full speed (0.05 … 1).
    ReplaySpeed(f64),
    /// Live: cap the run at this many simulated seconds per wall second (1: real time, 0.1: ten
    /// times slower than life); `None`: as fast as the back-end goes. Not applied while relaxing.
    Pace(Option<f64>),
    /// Replay: continue live from the current state; with a file, record a branch there.
    TakeOver(Option<std::path::PathBuf>),
    Quit,
}

/// Where a replay stands (for the timeline).
#[derive(Clone, Debug, Default)]
pub struct ReplayStatus {
    pub file: String,
    /// Step and time of the recording's end.
    pub end_step: u64,
    pub end_t: f64,
    /// Steps of the keyframes (where seeking is cheap).
    pub keyframes: Vec<u64>,
    /// Playback speed (fraction of full speed).
    pub speed: f64,
    pub at_end: bool,
    /// The recording branches off this one.
    pub parent: Option<String>,
    /// Container warnings (damaged or truncated file).
    pub warnings: Vec<String>,
}

/// The two render buffer sets of one scenario (rebuilt when the particle counts change).
pub struct FrameSet {
    pub sets: [FrameBuffers; 2],
    /// Distinguishes the sets of successive scenarios (bind groups are cached by it).
    pub generation: u64,
}

/// The last published set.
#[derive(Default)]
pub struct Published {
    pub frames: Option<Arc<FrameSet>>,
    /// Index of the front set (the one to draw).
    pub front: usize,
    pub info: FrameInfo,
}

/// Live statistics for the panels.
#[derive(Clone, Debug, Default)]
pub struct SimStatus {
    pub scenario: String,
    pub backend: String,
    pub t: f64,
    pub steps: u64,
    pub dt: f64,
    pub dt_limit: String,
    pub steps_per_s: f64,
    /// Simulated seconds per wall second.
    pub real_time_factor: f64,
    /// The live run's cap on the real-time factor (`Control::Pace`); `None`: uncapped.
    pub pace: Option<f64>,
    pub n_liquid: u32,
    pub n_solid: u32,
    pub broken_bonds: u64,
    pub paused: bool,
    pub relaxing: bool,
    /// The cached relaxed state this run started from (`replay::relaxed_cache`), instead of relaxing.
    pub relaxed_from: Option<String>,
    /// Set when the simulation diverged: it is paused with its last good state.
    pub diverged: Option<String>,
    /// A command or build failure to show (cleared by the next success).
    pub error: Option<String>,
    pub publishes: u64,
    /// The patient's vitals (scenarios with `physiology`), sampled every half second of wall time.
    pub vitals: Option<crate::sim::cardio::Vitals>,
    /// (t \[s\], MAP \[mmHg\], HR \[bpm\], blood lost \[mL\]) history for the panel's plot.
    pub vitals_history: Vec<[f64; 4]>,
    /// Set while replaying a recording.
    pub replay: Option<ReplayStatus>,
    /// The file being recorded and its size so far \[bytes\].
    pub recording: Option<(String, u64)>,
    /// Scenarios with a patient: the session's metrics so far (blood lost, peak loss rate, first cut,
    /// hemostasis).
    pub session: Option<crate::analysis::session::SessionReport>,
}

/// What the two threads share.
#[derive(Default)]
pub struct Shared {
    pub published: Mutex<Published>,
    pub status: Mutex<SimStatus>,
}

/// Locks a mutex, recovering the data if the other thread panicked while holding it.
pub fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Wall time a batch of steps aims at: short enough for commands to act within a few frames.
const BATCH_TARGET: Duration = Duration::from_millis(30);

/// Smallest and largest pace the viewer accepts (simulated seconds per wall second).
pub const PACE_RANGE: (f64, f64) = (1e-4, 10.0);

/// Wall time a batch that simulated `sim_dt` seconds takes at `pace` simulated seconds per wall
/// second: the next batch starts that long after this one started (the thread keeps answering
/// controls meanwhile). At most an hour; zero for a batch that did not advance the clock.
pub fn pace_wall(sim_dt: f64, pace: f64) -> Duration {
    if !(sim_dt > 0.0 && pace > 0.0) {
        return Duration::ZERO;
    }
    Duration::try_from_secs_f64((sim_dt / pace).min(3600.0)).unwrap_or(Duration::ZERO)
}

/// Steps per batch under a pace: no more than the pace lets the clock advance in one
/// `BATCH_TARGET` at step size `dt` (at least one), nor more than `want`.
pub fn paced_batch(want: u32, dt: f64, pace: f64) -> u32 {
    if !(dt > 0.0 && pace > 0.0) {
        return want;
    }
    let fit = (pace * BATCH_TARGET.as_secs_f64() / dt).floor();
    if fit >= want as f64 { want } else { (fit as u32).max(1) }
}

/// Steps per second and simulated seconds per wall second over the last ~second.
#[derive(Default)]
struct RateMeter {
    window_start: Option<Instant>,
    steps: u64,
    sim_time: f64,
    steps_per_s: f64,
    rtf: f64,
}

impl RateMeter {
    fn add(&mut self, steps: u64, sim_time: f64) {
        let now = Instant::now();
        let start = *self.window_start.get_or_insert(now);
        self.steps += steps;
        self.sim_time += sim_time;
        let wall = now.duration_since(start).as_secs_f64();
        if wall >= 1.0 {
            self.steps_per_s = self.steps as f64 / wall;
            self.rtf = self.sim_time / wall;
            *self = RateMeter { steps_per_s: self.steps_per_s, rtf: self.rtf, ..Default::default() };
        }
    }
}

/// Where a replay seeks to.
enum Target {
    Time(f64),
    Step(u64),
}

/// What the thread runs (one at a time, so the size difference costs nothing).
#[allow(clippy::large_enum_variant)]
enum Mode {
    Live(RecordedSimulation),
    Replay(Box<Player>),
}

struct Runner {
    ctx: GpuContext,
    use_gpu: bool,
    shared: Arc<Shared>,
    scenario: Scenario,
    sim: Option<Mode>,
    /// `--record FILE`: the first scenario run is recorded there (finished on reset, load or quit).
    record: Option<std::path::PathBuf>,
    /// `perfuse replay FILE`: replayed instead of the scenario at the first build.
    replay: Option<Recording>,
    replay_speed: f64,
    last_checkpoint: Instant,
    /// Stepping wall time since the last keyframe of the recording.
    since_keyframe: Duration,
    patient: Option<crate::sim::physiology::Patient>,
    /// The session's metrics, from the patient's samples.
    metrics: crate::analysis::session::SessionMetrics,
    last_vitals: Instant,
    frames: Option<Arc<FrameSet>>,
    generation: u64,
    front: usize,
    paused: bool,
    relax_end: Option<f64>,
    /// The live run's state at t = 0, taken when its relaxation ended, with the patient then: Reset
    /// restores it instead of relaxing the organ again (a trainee repeating a cut does not wait for the
    /// relaxation each time). Cleared when another scenario is loaded.
    relaxed: Option<Box<(crate::sim::snapshot::Snapshot, Option<crate::sim::physiology::Patient>)>>,
    /// Where relaxed states are kept between launches (`None`: not kept).
    relaxed_cache: Option<RelaxedCache>,
    /// Relax live even when a relaxed state is cached (and replace it).
    fresh_relaxation: bool,
    /// A command changed the live run while it relaxed (a tool moved, gravity changed): its relaxed
    /// state is then not the scenario's, and is not kept on disk.
    commanded_while_relaxing: bool,
    batch: u32,
    rate: RateMeter,
    /// `Control::Pace`: the live run's cap on simulated seconds per wall second.
    pace: Option<f64>,
    /// Under a pace, when the next batch may start.
    next_batch_at: Option<Instant>,
}

impl Runner {
    fn simulation(&self) -> Option<&Simulation> {
        self.sim.as_ref().map(Self::sim_of)
    }

    fn adapter(&self) -> String {
        if self.use_gpu { self.ctx.info.name.clone() } else { String::new() }
    }

    fn build(&mut self) {
        self.finish_recording();
        self.sim = None;
        self.next_batch_at = None;
        self.metrics = Default::default();
        let mut status = SimStatus {
            scenario: self.scenario.name.clone(),
            paused: self.paused,
            pace: self.pace,
            ..Default::default()
        };
        if let Some(rec) = self.replay.take() {
            self.build_replay(rec, &mut status);
        } else {
            self.build_live(&mut status);
        }
        if let Some(sim) = self.simulation() {
            let (nl, ns) = sim.frame_counts();
            (status.n_liquid, status.n_solid) = (nl, ns);
            // a run restored from the relaxed-state cache starts at t = 0 after the relaxation's steps
            (status.t, status.steps, status.broken_bonds) = (sim.time(), sim.stats().steps, sim.stats().broken_bonds);
            status.backend = sim.backend_name();
            self.generation += 1;
            let sets = [
                FrameBuffers::new(&self.ctx.device, nl, ns, "frame.a"),
                FrameBuffers::new(&self.ctx.device, nl, ns, "frame.b"),
            ];
            self.frames = Some(Arc::new(FrameSet { sets, generation: self.generation }));
            self.front = 1;
            self.batch = 1;
        }
        *lock(&self.shared.status) = status;
        self.publish();
    }

    fn new_patient(&self, status: &mut SimStatus) -> Option<crate::sim::physiology::Patient> {
        match self.scenario.physiology.as_ref().map(crate::sim::physiology::Patient::new) {
            Some(Ok(p)) => Some(p),
            Some(Err(e)) => {
                status.error = Some(format!("physiology: {e}"));
                None
            }
            None => None,
        }
    }

    fn build_live(&mut self, status: &mut SimStatus) {
        let sim = match Simulation::with_gpu(&self.scenario, self.use_gpu.then(|| self.ctx.clone())) {
            Ok(sim) => sim,
            Err(e) => {
                status.error = Some(format!("could not build `{}`: {e}", self.scenario.name));
                return;
            }
        };
        let recorder = match self.record.take() {
            Some(path) => match Recorder::create(&path, &self.scenario, &sim.backend_name(), &self.adapter()) {
                Ok(r) => {
                    log::info!("recording to {}", path.display());
                    status.recording = Some((path.display().to_string(), 0));
                    Some(r)
                }
                Err(e) => {
                    status.error = Some(format!("recording: {e}"));
                    None
                }
            },
            None => None,
        };
        let mut sim = RecordedSimulation { sim, recorder };
        self.patient = self.new_patient(status);
        // The scenario's damped relaxation runs live, before t = 0 (SPEC §7.5), unless this build has
        // kept the state it reaches (a recording then starts with a keyframe of it).
        self.relax_end = None;
        self.commanded_while_relaxing = false;
        if let Some(restored) = self.restore_cached(&mut sim.sim) {
            status.relaxed_from = Some(restored.file.display().to_string());
            if restored.patient.is_some() {
                self.patient = restored.patient.clone();
            }
            self.relaxed = Some(Box::new((restored.snapshot, self.patient.clone())));
            if let Err(e) = sim.keyframe(self.patient.as_ref()) {
                status.error = Some(format!("recording: {e}"));
            }
        } else if let Some(r) = self.scenario.relaxation.clone().filter(|r| r.duration > 0.0) {
            let setup = r.start_commands().iter().try_for_each(|c| sim.apply(c));
            match setup {
                Ok(()) => self.relax_end = Some(0.0),
                Err(e) => status.error = Some(e.to_string()),
            }
        }
        self.since_keyframe = Duration::ZERO;
        self.sim = Some(Mode::Live(sim));
    }

    /// The scenario's relaxed state from the cache, restored into `sim` (just built): `None` when the
    /// scenario has no relaxation, nothing is cached, `--fresh-relaxation` was given, or the cached
    /// file does not fit (reported; `sim` is then rebuilt if the restore touched it).
    fn restore_cached(&self, sim: &mut Simulation) -> Option<crate::replay::relaxed_cache::Restored> {
        let cache = self.relaxed_cache.as_ref().filter(|_| !self.fresh_relaxation)?;
        self.scenario.relaxation.as_ref().filter(|r| r.duration > 0.0)?;
        match cache.restore(&self.scenario, sim) {
            Ok(Some(r)) => {
                log::info!("relaxed state restored from {} (--fresh-relaxation relaxes again)", r.file.display());
                Some(r)
            }
            Ok(None) => None,
            Err(e) => {
                log::warn!("{e}");
                // a GPU restore that failed midway may have written part of the state
                if (self.use_gpu || sim.time() != 0.0 || sim.stats().steps != 0)
                    && let Ok(s) = Simulation::with_gpu(&self.scenario, self.use_gpu.then(|| self.ctx.clone()))
                {
                    *sim = s;
                }
                None
            }
        }
    }

    fn build_replay(&mut self, rec: Recording, status: &mut SimStatus) {
        let file = rec.source.clone();
        let built = recorded_scenario(&rec).and_then(|scenario| {
            let sim = Simulation::with_gpu(&scenario, self.use_gpu.then(|| self.ctx.clone())).map_err(|e| {
                crate::replay::session::SessionError::Sim { file: file.clone(), step: 0, source: Box::new(e) }
            })?;
            Ok((scenario, sim))
        });
        let (scenario, sim) = match built {
            Ok(b) => b,
            Err(e) => {
                status.error = Some(format!("cannot replay: {e}"));
                return;
            }
        };
        let keyframes: Vec<u64> = rec.chunks_of(crate::replay::format::ChunkKind::Keyframe).map(|c| c.step).collect();
        let parent = rec.header.parent.as_ref().map(|p| format!("{} at t = {:.4} s", p.file, p.t_s));
        let warnings = rec.warnings.iter().map(|w| w.to_string()).collect();
        match Player::with_simulation(rec, sim, false) {
            Ok(player) => {
                let (end_step, end_t) = player.end();
                self.scenario = scenario;
                status.scenario = self.scenario.name.clone();
                self.patient = player.patient().cloned().or_else(|| self.new_patient(status));
                status.replay = Some(ReplayStatus {
                    file,
                    end_step,
                    end_t,
                    keyframes,
                    speed: self.replay_speed,
                    at_end: false,
                    parent,
                    warnings,
                });
                self.relax_end = None;
                self.sim = Some(Mode::Replay(Box::new(player)));
            }
            Err(e) => status.error = Some(format!("cannot replay: {e}")),
        }
    }

    /// Ends the recording, if one runs: a last state hash, then the End chunk.
    fn finish_recording(&mut self) {
        if let Some(Mode::Live(rs)) = &mut self.sim
            && rs.recorder.is_some()
        {
            let _ = rs.checkpoint();
            if let Some(r) = rs.recorder.take() {
                match r.finish() {
                    Ok(bytes) => log::info!("recording finished: {bytes} bytes"),
                    Err(e) => log::error!("recording: {e}"),
                }
            }
        }
        lock(&self.shared.status).recording = None;
    }

    /// Starts recording the live session to `path`: the header, then a keyframe of the current state
    /// (the recording replays from it).
    fn start_recording(&mut self, path: std::path::PathBuf) {
        let adapter = self.adapter();
        let rs = match &mut self.sim {
            Some(Mode::Live(rs)) => rs,
            Some(Mode::Replay(_)) => {
                lock(&self.shared.status).error = Some("recording: take over the replay first (T)".into());
                return;
            }
            None => {
                lock(&self.shared.status).error = Some("recording: no simulation is running".into());
                return;
            }
        };
        if rs.recorder.is_some() {
            return;
        }
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            let _ = std::fs::create_dir_all(dir);
        }
        let r = Recorder::create(&path, &self.scenario, &rs.sim.backend_name(), &adapter)
            .map_err(|e| e.to_string())
            .and_then(|r| {
                rs.recorder = Some(r);
                rs.keyframe(self.patient.as_ref()).map_err(|e| e.to_string())
            });
        let mut st = lock(&self.shared.status);
        match r {
            Ok(()) => {
                log::info!("recording to {}", path.display());
                st.recording = Some((path.display().to_string(), 0));
                self.since_keyframe = Duration::ZERO;
            }
            Err(e) => st.error = Some(format!("recording: {e}")),
        }
    }

    /// Replay → live from the current state, optionally recording a branch.
    fn take_over(&mut self, branch: Option<std::path::PathBuf>) {
        let Some(Mode::Replay(player)) = self.sim.take() else { return };
        let backend = player.simulation().backend_name();
        let adapter = self.adapter();
        if let Some(dir) = branch.as_ref().and_then(|p| p.parent()).filter(|d| !d.as_os_str().is_empty()) {
            let _ = std::fs::create_dir_all(dir);
        }
        let spec = branch.as_ref().map(|p| (p.as_path(), backend.as_str(), adapter.as_str()));
        match player.take_over(spec) {
            Ok((rs, patient)) => {
                let t = rs.sim.time();
                let mut st = lock(&self.shared.status);
                if let Some(p) = patient {
                    self.patient = Some(p);
                }
                // taken over during the relaxation: end it live, as a live run does
                self.relax_end = (t < 0.0).then_some(0.0);
                st.replay = None;
                st.recording = branch.as_ref().map(|p| (p.display().to_string(), 0));
                st.error = None;
                drop(st);
                self.since_keyframe = Duration::ZERO;
                self.sim = Some(Mode::Live(rs));
            }
            Err(e) => {
                // the player is gone with its simulation: rebuild the scenario live
                lock(&self.shared.status).error = Some(format!("take-over failed: {e}"));
                self.build();
            }
        }
    }

    /// Writes the back set and swaps it to the front.
    fn publish(&mut self) {
        let (Some(sim), Some(frames)) = (self.simulation(), &self.frames) else { return };
        let back = 1 - self.front;
        match sim.publish(&frames.sets[back], &self.ctx.queue) {
            Ok(info) => {
                self.front = back;
                let mut p = lock(&self.shared.published);
                p.frames = Some(frames.clone());
                p.front = back;
                p.info = info;
                lock(&self.shared.status).publishes += 1;
            }
            Err(e) => lock(&self.shared.status).error = Some(e.to_string()),
        }
    }

    fn handle(&mut self, c: Control) -> bool {
        match c {
            Control::Quit => {
                self.finish_recording();
                return false;
            }
            Control::Pause(p) => {
                self.paused = p;
                lock(&self.shared.status).paused = p;
            }
            Control::Step => {
                if self.paused {
                    self.advance(1);
                }
            }
            Control::Reset => {
                if matches!(self.sim, Some(Mode::Replay(_))) {
                    self.seek(Target::Step(0));
                } else if !self.restore_relaxed() {
                    self.build();
                }
            }
            Control::Load(s) => {
                self.scenario = *s;
                self.relaxed = None;
                self.build();
            }
            Control::Sim(cmd) => match &mut self.sim {
                Some(Mode::Live(sim)) => {
                    let r = sim.apply(&cmd);
                    self.commanded_while_relaxing |= r.is_ok() && self.relax_end.is_some();
                    let mut st = lock(&self.shared.status);
                    st.error = r.err().map(|e| e.to_string());
                }
                Some(Mode::Replay(_)) => {
                    lock(&self.shared.status).error =
                        Some("replaying: take over (T) to drive the tools from here".into());
                }
                None => {}
            },
            Control::Record(Some(path)) => self.start_recording(path),
            Control::Record(None) => self.finish_recording(),
            Control::Seek(t) => self.seek(Target::Time(t)),
            Control::SeekStep(n) => self.seek(Target::Step(n)),
            Control::ReplaySpeed(s) => {
                self.replay_speed = if s.is_finite() { s.clamp(0.05, 1.0) } else { 1.0 };
                if let Some(r) = &mut lock(&self.shared.status).replay {
                    r.speed = self.replay_speed;
                }
            }
            Control::Pace(p) => {
                self.pace = p.filter(|r| r.is_finite() && *r > 0.0).map(|r| r.clamp(PACE_RANGE.0, PACE_RANGE.1));
                self.next_batch_at = None;
                lock(&self.shared.status).pace = self.pace;
            }
            Control::TakeOver(branch) => self.take_over(branch),
        }
        true
    }

    /// Replay: go to a time or step.
    fn seek(&mut self, target: Target) {
        let Some(Mode::Replay(player)) = &mut self.sim else { return };
        let r = match target {
            Target::Step(n) => player.seek_step(n),
            Target::Time(t) => player.seek_time(t),
        };
        let patient = player.patient().cloned();
        let (time, steps, at_end) = (player.simulation().time(), player.steps(), player.at_end());
        let broken = player.simulation().stats().broken_bonds;
        {
            let mut st = lock(&self.shared.status);
            (st.t, st.steps, st.broken_bonds) = (time, steps, broken);
            st.error = r.err().map(|e| e.to_string());
            st.vitals_history.clear();
            if let Some(rs) = &mut st.replay {
                rs.at_end = at_end;
            }
        }
        if patient.is_some() {
            self.patient = patient;
        }
        self.publish();
    }

    /// Takes up to `steps` steps (stopping at the end of the relaxation, or of a replay), updating
    /// the status.
    fn advance(&mut self, steps: u32) {
        let relax_end = self.relax_end;
        self.next_batch_at = None;
        let Some(mode) = &mut self.sim else { return };
        let (t0, start) = (Self::sim_of(mode).time(), Instant::now());
        let r = match mode {
            Mode::Live(rs) => {
                // The patient's hepatic flow feeds the `Hepatic` inlets (after the relaxation, as
                // headless runs do): a table renewed half a horizon before it runs out, recorded like
                // every command.
                if let Some(p) = self.patient.as_mut()
                    && relax_end.is_none()
                    && rs.sim.time() + 0.5 * crate::sim::physiology::INFLOW_HORIZON_S >= p.inflow_until()
                {
                    let t = rs.sim.time();
                    for k in rs.sim.hepatic_emitters() {
                        let cmd = p.inflow(k, t, t.max(0.0) + crate::sim::physiology::INFLOW_HORIZON_S);
                        if let Err(e) = rs.apply(&cmd) {
                            lock(&self.shared.status).error = Some(e.to_string());
                        }
                    }
                }
                rs.sim.advance(steps, relax_end.unwrap_or(f64::INFINITY)).map(Some)
            }
            Mode::Replay(player) => player.step_forward(steps).map(|_| None).map_err(|e| match e {
                crate::replay::session::SessionError::Sim { source, .. } => *source,
                other => SimError::BadCommand(other.to_string()),
            }),
        };
        let wall = start.elapsed();
        let sim = Self::sim_of(mode);
        let (t1, n_steps) = (sim.time(), sim.stats().steps);
        let mut st = lock(&self.shared.status);
        match r {
            Ok(adv) => {
                let taken = adv.as_ref().map_or(n_steps.saturating_sub(st.steps), |a| a.steps);
                self.rate.add(taken, t1 - t0);
                st.t = t1;
                if let Some(adv) = &adv {
                    st.dt = adv.dt_max;
                    if let Some((i, _)) = adv.limited_by.iter().enumerate().max_by_key(|(_, n)| **n)
                        && adv.steps > 0
                    {
                        st.dt_limit = DtLimit::ALL[i].name().to_string();
                    }
                }
                // Aim the next batch at BATCH_TARGET of wall time.
                if taken > 0 {
                    let per_step = wall.as_secs_f64() / taken as f64;
                    let want = (BATCH_TARGET.as_secs_f64() / per_step.max(1e-6)).clamp(1.0, 64.0);
                    self.batch = want as u32;
                    // A paced live run takes no more steps than the pace lets the clock advance.
                    if let (Some(pace), Mode::Live(_), None) = (self.pace, &*mode, relax_end) {
                        self.batch = paced_batch(self.batch, (t1 - t0) / taken as f64, pace);
                    }
                }
            }
            Err(e) => {
                // A diverged run keeps its last good state: pause and say so.
                if matches!(e, SimError::Diverged { .. }) {
                    st.diverged = Some(e.to_string());
                } else {
                    st.error = Some(e.to_string());
                }
                self.paused = true;
                st.paused = true;
            }
        }
        st.steps = n_steps;
        st.broken_bonds = sim.stats().broken_bonds;
        (st.n_liquid, st.n_solid) = sim.particle_counts();
        st.steps_per_s = self.rate.steps_per_s;
        st.real_time_factor = self.rate.rtf;
        drop(st);
        match mode {
            Mode::Live(rs) => {
                // A paced run waits for the clock before its next batch (not while relaxing).
                self.next_batch_at = match (self.pace, relax_end) {
                    (Some(pace), None) => Some(start + pace_wall(t1 - t0, pace)),
                    _ => None,
                };
                self.since_keyframe += wall;
                let relaxed = Self::after_live_batch(
                    rs,
                    &self.shared,
                    &mut self.relax_end,
                    &mut self.since_keyframe,
                    self.patient.as_ref(),
                );
                // Keep the relaxed state for Reset (one readback on the GPU, once per scenario).
                if relaxed && self.relaxed.is_none() {
                    match rs.sim.snapshot() {
                        Ok(snap) => {
                            match &self.relaxed_cache {
                                Some(_) if self.commanded_while_relaxing => log::info!(
                                    "the relaxed state is not kept for the next launch: commands changed the run \
                                     while it relaxed"
                                ),
                                Some(cache) => {
                                    Self::keep_on_disk(cache, &self.scenario, &rs.sim, &snap, self.patient.as_ref())
                                }
                                None => {}
                            }
                            self.relaxed = Some(Box::new((snap, self.patient.clone())));
                        }
                        Err(e) => log::warn!("the relaxed state could not be kept for Reset: {e}"),
                    }
                }
                let mut st = lock(&self.shared.status);
                if let (Some(r), Some(rec)) = (&rs.recorder, &mut st.recording) {
                    rec.1 = r.bytes_written();
                }
            }
            Mode::Replay(player) => {
                let at_end = player.at_end();
                let mut st = lock(&self.shared.status);
                if let Some(r) = &mut st.replay {
                    r.at_end = at_end;
                }
                if at_end {
                    self.paused = true;
                    st.paused = true;
                }
                drop(st);
                // Slower playback: idle so that stepping takes `speed` of the wall time.
                if self.replay_speed < 1.0 {
                    std::thread::sleep(wall.mul_f64((1.0 / self.replay_speed - 1.0).min(20.0)));
                }
            }
        }
        self.sample_patient();
        self.checkpoint();
        self.publish();
    }

    fn sim_of(mode: &Mode) -> &Simulation {
        match mode {
            Mode::Live(rs) => &rs.sim,
            Mode::Replay(p) => p.simulation(),
        }
    }

    /// End of the relaxation (undamped from t = 0, a keyframe; returns whether it ended now) and the
    /// periodic keyframes of a recording.
    fn after_live_batch(
        rs: &mut RecordedSimulation,
        shared: &Shared,
        relax_end: &mut Option<f64>,
        since_keyframe: &mut Duration,
        patient: Option<&crate::sim::physiology::Patient>,
    ) -> bool {
        let mut relaxed = false;
        let mut keyframe = *since_keyframe >= KEYFRAME_EVERY;
        if let Some(t_end) = *relax_end
            && rs.sim.time() >= t_end
        {
            let hold = rs.sim.scenario().relaxation.as_ref().is_some_and(|r| r.hold_suction);
            let r = crate::scenario::Relaxation::end(hold).iter().try_for_each(|c| rs.apply(c));
            if let Err(e) = r {
                lock(&shared.status).error = Some(e.to_string());
            }
            *relax_end = None;
            keyframe = true;
            relaxed = true;
        }
        lock(&shared.status).relaxing = relax_end.is_some();
        if keyframe && rs.recorder.is_some() {
            *since_keyframe = Duration::ZERO;
            if let Err(e) = rs.keyframe(patient) {
                lock(&shared.status).error = Some(format!("recording: {e}"));
            }
        }
        relaxed
    }

    /// Writes the relaxed state to the cache on a thread of its own (compressing a large organ's state
    /// takes a moment the simulation need not wait for).
    fn keep_on_disk(
        cache: &RelaxedCache,
        scenario: &Scenario,
        sim: &Simulation,
        snap: &crate::sim::snapshot::Snapshot,
        patient: Option<&crate::sim::physiology::Patient>,
    ) {
        let (cache, scenario, snap, patient) = (cache.clone(), scenario.clone(), snap.clone(), patient.cloned());
        let engine = crate::replay::relaxed_cache::Engine::of(sim);
        let spawned = std::thread::Builder::new().name("relaxed-cache".into()).spawn(move || {
            match cache.store(&scenario, &engine, &snap, patient.as_ref()) {
                Ok(f) => log::info!("relaxed state kept in {} for the next launch", f.display()),
                Err(e) => log::warn!("{e}"),
            }
        });
        if let Err(e) = spawned {
            log::warn!("the relaxed state is not kept for the next launch: {e}");
        }
    }

    /// Reset of a live run whose relaxation has been kept: the simulation goes back to that state (the
    /// recording, if any, ends as on every reset; one started later begins with a keyframe of it).
    /// Returns false when there is none to restore or restoring failed: the caller then rebuilds.
    fn restore_relaxed(&mut self) -> bool {
        let Some(kept) = self.relaxed.as_ref() else { return false };
        if !matches!(self.sim, Some(Mode::Live(_))) {
            return false;
        }
        let (snap, patient) = (kept.0.clone(), kept.1.clone());
        self.finish_recording();
        let Some(Mode::Live(rs)) = &mut self.sim else { return false };
        if let Err(e) = rs.sim.restore(snap) {
            log::warn!("reset: the relaxed state could not be restored ({e}); rebuilding the scenario");
            self.relaxed = None;
            return false;
        }
        self.relax_end = None;
        self.next_batch_at = None;
        self.since_keyframe = Duration::ZERO;
        self.metrics = Default::default();
        self.patient = patient;
        let sim = &rs.sim;
        let (n_liquid, n_solid) = sim.particle_counts();
        let (publishes, relaxed_from) = {
            let st = lock(&self.shared.status);
            (st.publishes, st.relaxed_from.clone())
        };
        let status = SimStatus {
            scenario: self.scenario.name.clone(),
            backend: sim.backend_name(),
            t: sim.time(),
            steps: sim.stats().steps,
            broken_bonds: sim.stats().broken_bonds,
            n_liquid,
            n_solid,
            paused: self.paused,
            pace: self.pace,
            publishes,
            relaxed_from,
            ..Default::default()
        };
        *lock(&self.shared.status) = status;
        log::info!("reset to the relaxed state at t = {:.3} s (no new relaxation)", sim.time());
        self.publish();
        true
    }

    /// The patient, from a readback every half second of wall time (not per step). In a replay it
    /// follows the organ's loss for the vitals panel; its inflow comes from the recording.
    fn sample_patient(&mut self) {
        if self.patient.is_none() || self.last_vitals.elapsed() <= Duration::from_millis(500) {
            return;
        }
        self.last_vitals = Instant::now();
        let rho0 = self.scenario.liquid.as_ref().map_or(1000.0, |l| l.density);
        let state = match &mut self.sim {
            Some(Mode::Live(rs)) => rs.sim.read_state(),
            Some(Mode::Replay(p)) => p.simulation_mut().read_state(),
            None => return,
        };
        match (state, self.patient.as_mut()) {
            (Ok(state), Some(p)) => {
                let v = p.update(&state, rho0);
                self.metrics.push(state.t, v.blood_lost_ml, state.broken_bonds());
                let mut st = lock(&self.shared.status);
                st.vitals = Some(v);
                st.session = Some(self.metrics.report().clone());
                st.vitals_history.push([state.t, v.map_mmhg, v.hr_bpm, v.blood_lost_ml]);
                if st.vitals_history.len() > 2000 {
                    st.vitals_history.drain(..1000);
                }
            }
            (Err(e), _) => lock(&self.shared.status).error = Some(e.to_string()),
            _ => {}
        }
    }

    /// A state hash every [`HASH_EVERY`] of wall time lets `perfuse replay --verify` check the recording.
    fn checkpoint(&mut self) {
        let Some(Mode::Live(rs)) = &mut self.sim else { return };
        if rs.recorder.is_some() && self.last_checkpoint.elapsed() > HASH_EVERY {
            self.last_checkpoint = Instant::now();
            if let Err(e) = rs.checkpoint() {
                lock(&self.shared.status).error = Some(format!("recording: {e}"));
            }
        }
    }

    fn run(mut self, rx: Receiver<Control>) {
        self.build();
        loop {
            // Apply everything queued; while paused, wait for the next message.
            let mut dirty = false;
            loop {
                let msg = if self.paused && !dirty {
                    match rx.recv_timeout(Duration::from_millis(50)) {
                        Ok(m) => Some(m),
                        Err(RecvTimeoutError::Timeout) => None,
                        Err(RecvTimeoutError::Disconnected) => return,
                    }
                } else {
                    rx.try_recv().ok()
                };
                let Some(m) = msg else { break };
                let is_step = matches!(m, Control::Step);
                if !self.handle(m) {
                    return;
                }
                dirty |= !is_step;
            }
            if self.paused {
                if dirty {
                    self.publish();
                }
                continue;
            }
            // Paced: wait for the clock, answering controls meanwhile.
            if let Some(at) = self.next_batch_at {
                let now = Instant::now();
                if now < at {
                    match rx.recv_timeout((at - now).min(Duration::from_millis(50))) {
                        Ok(m) => {
                            let publish = !matches!(m, Control::Step);
                            if !self.handle(m) {
                                return;
                            }
                            if publish {
                                self.publish();
                            }
                        }
                        Err(RecvTimeoutError::Timeout) => {}
                        Err(RecvTimeoutError::Disconnected) => return,
                    }
                    continue;
                }
            }
            self.advance(self.batch);
        }
    }
}

/// How the simulation thread starts.
pub struct Start {
    /// Simulate on the GPU of the context (else on the CPU, publishing through its queue).
    pub use_gpu: bool,
    pub scenario: Scenario,
    pub paused: bool,
    /// Record the first run of the scenario to this file.
    pub record: Option<std::path::PathBuf>,
    /// Replay this recording instead (its own scenario).
    pub replay: Option<Recording>,
    /// Keep relaxed states here between launches and start from them (`replay::relaxed_cache`).
    pub relaxed_cache: Option<RelaxedCache>,
    /// Relax live even when a relaxed state is cached (the new one replaces it).
    pub fresh_relaxation: bool,
}

/// Starts the simulation thread on `scenario`; the simulation runs on the GPU of `ctx` when
/// `use_gpu`, else on the CPU (publishing through `ctx`'s queue either way).
pub fn spawn(
    ctx: GpuContext,
    use_gpu: bool,
    scenario: Scenario,
    paused: bool,
    record: Option<std::path::PathBuf>,
    rx: Receiver<Control>,
    shared: Arc<Shared>,
) -> std::io::Result<std::thread::JoinHandle<()>> {
    let start = Start { use_gpu, scenario, paused, record, replay: None, relaxed_cache: None, fresh_relaxation: false };
    spawn_with(ctx, start, rx, shared)
}

/// Starts the simulation thread as `start` says.
pub fn spawn_with(
    ctx: GpuContext,
    start: Start,
    rx: Receiver<Control>,
    shared: Arc<Shared>,
) -> std::io::Result<std::thread::JoinHandle<()>> {
    let runner = Runner {
        ctx,
        use_gpu: start.use_gpu,
        shared,
        scenario: start.scenario,
        sim: None,
        record: start.record,
        replay: start.replay,
        replay_speed: 1.0,
        last_checkpoint: Instant::now(),
        since_keyframe: Duration::ZERO,
        patient: None,
        metrics: Default::default(),
        last_vitals: Instant::now(),
        frames: None,
        generation: 0,
        front: 1,
        paused: start.paused,
        relax_end: None,
        relaxed: None,
        relaxed_cache: start.relaxed_cache,
        fresh_relaxation: start.fresh_relaxation,
        commanded_while_relaxing: false,
        pace: None,
        next_batch_at: None,
        batch: 1,
        rate: RateMeter::default(),
    };
    std::thread::Builder::new().name("perfuse-sim".into()).spawn(move || runner.run(rx))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A batch that simulated 1 ms at a pace of 0.01 should take 0.1 s of wall time; a batch that
    /// did not advance, or a nonsensical pace, waits for nothing; absurd ratios stop at an hour.
    #[test]
    fn pace_wall_is_the_batch_time_over_the_pace() {
        assert_eq!(pace_wall(1e-3, 0.01), Duration::from_millis(100));
        assert_eq!(pace_wall(0.5, 1.0), Duration::from_millis(500));
        assert_eq!(pace_wall(0.0, 0.01), Duration::ZERO);
        assert_eq!(pace_wall(1e-3, 0.0), Duration::ZERO);
        assert_eq!(pace_wall(f64::NAN, 1.0), Duration::ZERO);
        assert_eq!(pace_wall(1e9, 1e-4), Duration::from_secs(3600));
    }

    /// Under a pace a batch holds no more steps than the pace lets the clock advance in one
    /// BATCH_TARGET (30 ms), at least one, never more than the unpaced size.
    #[test]
    fn paced_batch_fits_the_pace() {
        // 1 s per wall s, Δt = 1 ms: 30 steps in 30 ms; capped by want.
        assert_eq!(paced_batch(64, 1e-3, 1.0), 30);
        assert_eq!(paced_batch(10, 1e-3, 1.0), 10);
        // Slow motion: fewer than one step per batch still takes one.
        assert_eq!(paced_batch(64, 5e-5, 1e-4), 1);
        // No pace information: unchanged.
        assert_eq!(paced_batch(64, 0.0, 1.0), 64);
    }
}
