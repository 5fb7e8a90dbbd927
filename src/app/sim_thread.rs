//! The simulation thread of the viewer: it owns the [`Simulation`], steps it as fast as it can (in
//! batches sized to about 30 ms of wall time, so commands and publication stay responsive), and after
//! each batch writes the back set of the two render buffer sets and publishes it by swapping an
//! index (DESIGN §Double buffering). It never waits for a frame; the render thread never waits for
//! it. The viewer reaches it only through [`Control`] messages on a channel — the same
//! [`Command`]s a recording holds, plus run control.

use crate::replay::session::{RecordedSimulation, Recorder};
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
    /// Load another scenario.
    Load(Box<Scenario>),
    Quit,
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
    pub n_liquid: u32,
    pub n_solid: u32,
    pub broken_bonds: u64,
    pub paused: bool,
    pub relaxing: bool,
    /// Set when the simulation diverged: it is paused with its last good state.
    pub diverged: Option<String>,
    /// A command or build failure to show (cleared by the next success).
    pub error: Option<String>,
    pub publishes: u64,
    /// The patient's vitals (scenarios with `physiology`), sampled every half second of wall time.
    pub vitals: Option<crate::sim::cardio::Vitals>,
    /// (t [s], MAP [mmHg], HR [bpm], blood lost [mL]) history for the panel's plot.
    pub vitals_history: Vec<[f64; 4]>,
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

struct Runner {
    ctx: GpuContext,
    use_gpu: bool,
    shared: Arc<Shared>,
    scenario: Scenario,
    sim: Option<RecordedSimulation>,
    /// `--record FILE`: the first scenario run is recorded there (finished on reset, load or quit).
    record: Option<std::path::PathBuf>,
    last_checkpoint: Instant,
    patient: Option<crate::sim::physiology::Patient>,
    last_vitals: Instant,
    frames: Option<Arc<FrameSet>>,
    generation: u64,
    front: usize,
    paused: bool,
    relax_end: Option<f64>,
    batch: u32,
    rate: RateMeter,
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

impl Runner {
    fn build(&mut self) {
        self.finish_recording();
        self.sim = None;
        let mut status = SimStatus { scenario: self.scenario.name.clone(), paused: self.paused, ..Default::default() };
        match Simulation::with_gpu(&self.scenario, self.use_gpu.then(|| self.ctx.clone())) {
            Ok(sim) => {
                status.backend = sim.backend_name();
                let recorder = match self.record.take() {
                    Some(path) => {
                        let adapter = if self.use_gpu { self.ctx.info.name.clone() } else { String::new() };
                        match Recorder::create(&path, &self.scenario, &sim.backend_name(), &adapter) {
                            Ok(r) => {
                                log::info!("recording to {}", path.display());
                                Some(r)
                            }
                            Err(e) => {
                                status.error = Some(format!("recording: {e}"));
                                None
                            }
                        }
                    }
                    None => None,
                };
                let mut sim = RecordedSimulation { sim, recorder };
                self.patient = match self.scenario.physiology.as_ref().map(crate::sim::physiology::Patient::new) {
                    Some(Ok(p)) => Some(p),
                    Some(Err(e)) => {
                        status.error = Some(format!("physiology: {e}"));
                        None
                    }
                    None => None,
                };
                // The scenario's damped relaxation runs live, before t = 0 (SPEC §7.5).
                self.relax_end = None;
                if let Some(r) = self.scenario.relaxation.clone().filter(|r| r.duration > 0.0) {
                    let setup = sim.apply(&Command::SetTime(-r.duration)).and_then(|_| {
                        sim.apply(&Command::SetDamping { damping: r.damping, gravity_solid_only: r.gravity_solid_only })
                    });
                    match setup {
                        Ok(()) => self.relax_end = Some(0.0),
                        Err(e) => status.error = Some(e.to_string()),
                    }
                }
                let (nl, ns) = sim.sim.frame_counts();
                (status.n_liquid, status.n_solid) = (nl, ns);
                self.generation += 1;
                let sets = [
                    FrameBuffers::new(&self.ctx.device, nl, ns, "frame.a"),
                    FrameBuffers::new(&self.ctx.device, nl, ns, "frame.b"),
                ];
                self.frames = Some(Arc::new(FrameSet { sets, generation: self.generation }));
                self.front = 1;
                self.sim = Some(sim);
                self.batch = 1;
            }
            Err(e) => status.error = Some(format!("could not build `{}`: {e}", self.scenario.name)),
        }
        *lock(&self.shared.status) = status;
        self.publish();
    }

    /// Ends the recording, if one runs: a last state hash, then the End chunk.
    fn finish_recording(&mut self) {
        if let Some(rs) = &mut self.sim
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
    }

    /// Writes the back set and swaps it to the front.
    fn publish(&mut self) {
        let (Some(rs), Some(frames)) = (&self.sim, &self.frames) else { return };
        let back = 1 - self.front;
        match rs.sim.publish(&frames.sets[back], &self.ctx.queue) {
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
            Control::Reset => self.build(),
            Control::Load(s) => {
                self.scenario = *s;
                self.build();
            }
            Control::Sim(cmd) => {
                if let Some(sim) = &mut self.sim {
                    let r = sim.apply(&cmd);
                    let mut st = lock(&self.shared.status);
                    st.error = r.err().map(|e| e.to_string());
                }
            }
        }
        true
    }

    /// Takes up to `steps` steps (stopping at the end of the relaxation), updating the status.
    fn advance(&mut self, steps: u32) {
        let Some(rs) = &mut self.sim else { return };
        // The patient's hepatic flow feeds the `Hepatic` inlets (after the relaxation, as headless
        // runs do): a table renewed half a horizon before it runs out, recorded like every command.
        if let Some(p) = self.patient.as_mut()
            && self.relax_end.is_none()
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
        let t0 = rs.sim.time();
        let t_end = self.relax_end.unwrap_or(f64::INFINITY);
        let start = Instant::now();
        let r = rs.sim.advance(steps, t_end);
        let wall = start.elapsed();
        let mut st = lock(&self.shared.status);
        match r {
            Ok(adv) => {
                self.rate.add(adv.steps, adv.t - t0);
                st.t = adv.t;
                st.dt = adv.dt_max;
                if let Some((i, _)) = adv.limited_by.iter().enumerate().max_by_key(|(_, n)| **n)
                    && adv.steps > 0
                {
                    st.dt_limit = DtLimit::ALL[i].name().to_string();
                }
                // Aim the next batch at BATCH_TARGET of wall time.
                if adv.steps > 0 {
                    let per_step = wall.as_secs_f64() / adv.steps as f64;
                    let want = (BATCH_TARGET.as_secs_f64() / per_step.max(1e-6)).clamp(1.0, 64.0);
                    self.batch = want as u32;
                }
            }
            Err(e) => {
                // A diverged run keeps its last good state: pause and say so.
                if matches!(e, SimError::Diverged { .. }) {
                    st.diverged = Some(e.to_string());
                    self.paused = true;
                    st.paused = true;
                } else {
                    st.error = Some(e.to_string());
                    self.paused = true;
                    st.paused = true;
                }
            }
        }
        st.steps = rs.sim.stats().steps;
        st.broken_bonds = rs.sim.stats().broken_bonds;
        (st.n_liquid, st.n_solid) = rs.sim.particle_counts();
        st.steps_per_s = self.rate.steps_per_s;
        st.real_time_factor = self.rate.rtf;
        // End of the relaxation: undamped from t = 0.
        if let Some(t_end) = self.relax_end
            && rs.sim.time() >= t_end
        {
            let r = rs
                .apply(&Command::SetDamping { damping: 0.0, gravity_solid_only: false })
                .and_then(|_| rs.apply(&Command::SetTime(0.0)));
            if let Err(e) = r {
                st.error = Some(e.to_string());
            }
            self.relax_end = None;
        }
        st.relaxing = self.relax_end.is_some();
        drop(st);
        // The patient, from a readback every half second of wall time (not per step).
        if self.patient.is_some() && self.last_vitals.elapsed() > Duration::from_millis(500) {
            self.last_vitals = Instant::now();
            let rho0 = self.scenario.liquid.as_ref().map_or(1000.0, |l| l.density);
            match (rs.sim.read_state(), self.patient.as_mut()) {
                (Ok(state), Some(p)) => {
                    let v = p.update(&state, rho0);
                    let mut st = lock(&self.shared.status);
                    st.vitals = Some(v);
                    st.vitals_history.push([state.t, v.map_mmhg, v.hr_bpm, v.blood_lost_ml]);
                    if st.vitals_history.len() > 2000 {
                        st.vitals_history.drain(..1000);
                    }
                }
                (Err(e), _) => lock(&self.shared.status).error = Some(e.to_string()),
                _ => {}
            }
        }
        // A state hash every 2 s of wall time lets `perfuse replay --verify` check the recording.
        if rs.recorder.is_some() && self.last_checkpoint.elapsed() > Duration::from_secs(2) {
            self.last_checkpoint = Instant::now();
            if let Err(e) = rs.checkpoint() {
                lock(&self.shared.status).error = Some(format!("recording: {e}"));
            }
        }
        self.publish();
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
            self.advance(self.batch);
        }
    }
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
    let runner = Runner {
        ctx,
        use_gpu,
        shared,
        scenario,
        sim: None,
        record,
        last_checkpoint: Instant::now(),
        patient: None,
        last_vitals: Instant::now(),
        frames: None,
        generation: 0,
        front: 1,
        paused,
        relax_end: None,
        batch: 1,
        rate: RateMeter::default(),
    };
    std::thread::Builder::new().name("perfuse-sim".into()).spawn(move || runner.run(rx))
}
