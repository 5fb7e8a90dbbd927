//! Recording and replaying sessions on top of the container (`format`): a [`Recorder`] writes the
//! scenario (as RON, mesh paths made absolute) into the header, every command applied to the
//! simulation as a `Commands` chunk stamped with the step it acts before, and `StateHash` chunks; the
//! player rebuilds the simulation from the header and feeds it the same commands at the same steps —
//! the same code path as live use — checking the hashes on the way (`perfuse replay --verify`). On one
//! adapter a replay is bit-identical (DESIGN: determinism).

use super::format::{ChunkKind, Header, Recording, RecordingWriter, ReplayError};
use crate::scenario::{Generator, Scenario};
use crate::sim::{BackendKind, Command, SimError, Simulation};
use std::path::Path;

/// Why a replay failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SessionError {
    #[error(transparent)]
    Format(#[from] ReplayError),
    #[error("recording {file}: its scenario does not load: {detail}")]
    Scenario { file: String, detail: String },
    #[error("recording {file}: chunk at step {step} holds an unreadable command list: {detail}")]
    BadCommands { file: String, step: u64, detail: String },
    #[error("recording {file}: replay failed at step {step}: {source}")]
    Sim { file: String, step: u64, source: Box<SimError> },
}

/// The scenario as self-contained RON: relative mesh paths resolved against its folder.
pub fn scenario_text(s: &Scenario) -> String {
    let mut s = s.clone();
    for g in &mut s.particles {
        if let Generator::PerfusedMesh { file, .. } = g {
            let abs = s.base_dir.as_ref().map(|d| d.join(&*file)).unwrap_or_else(|| file.clone().into());
            *file = std::fs::canonicalize(&abs).unwrap_or(abs).display().to_string();
        }
    }
    ron::ser::to_string_pretty(&s, ron::ser::PrettyConfig::default()).unwrap_or_default()
}

/// Writes a session: header, commands, state hashes.
pub struct Recorder {
    writer: RecordingWriter<std::fs::File>,
}

impl Recorder {
    /// Starts a recording of `scenario` simulated on `backend` (adapter name for the GPU).
    pub fn create(path: &Path, scenario: &Scenario, backend: &str, adapter: &str) -> Result<Recorder, ReplayError> {
        let header = Header::new(
            concat!("perfuse ", env!("CARGO_PKG_VERSION")),
            backend,
            adapter,
            scenario.name.clone(),
            scenario_text(scenario),
        );
        Ok(Recorder { writer: RecordingWriter::create(path, &header)? })
    }

    /// Records `cmd`, applied after `step` steps at time `t`.
    pub fn command(&mut self, step: u64, t: f64, cmd: &Command) -> Result<(), ReplayError> {
        let payload = serde_json::to_vec(&[cmd]).unwrap_or_default();
        self.writer.write_chunk(ChunkKind::Commands, t, step, &payload)
    }

    /// Records the state hash after `step` steps.
    pub fn state_hash(&mut self, step: u64, t: f64, hash: u64) -> Result<(), ReplayError> {
        self.writer.write_chunk(ChunkKind::StateHash, t, step, &hash.to_le_bytes())
    }

    pub fn flush(&mut self) -> Result<(), ReplayError> {
        self.writer.flush()
    }

    pub fn bytes_written(&self) -> u64 {
        self.writer.bytes_written()
    }

    /// Writes the End chunk; returns the file size.
    pub fn finish(self) -> Result<u64, ReplayError> {
        let bytes = self.writer.bytes_written();
        self.writer.finish()?;
        Ok(bytes)
    }
}

/// A simulation that records every command it applies (the viewer's simulation thread, scripted
/// sessions in tests).
pub struct RecordedSimulation {
    pub sim: Simulation,
    pub recorder: Option<Recorder>,
}

impl RecordedSimulation {
    /// Applies `cmd` and records it (a refused command is not recorded: it changed nothing).
    pub fn apply(&mut self, cmd: &Command) -> Result<(), SimError> {
        let (step, t) = (self.sim.stats().steps, self.sim.time());
        self.sim.apply(cmd)?;
        if let Some(r) = &mut self.recorder
            && let Err(e) = r.command(step, t, cmd)
        {
            log::error!("recording stopped: {e}");
            self.recorder = None;
        }
        Ok(())
    }

    /// The scenario's damped relaxation (as `Simulation::relax`), its commands recorded.
    pub fn relax(&mut self) -> Result<(), SimError> {
        let Some(r) = self.sim.scenario().relaxation.clone() else { return Ok(()) };
        if r.duration <= 0.0 {
            return Ok(());
        }
        self.apply(&Command::SetTime(-r.duration))?;
        self.apply(&Command::SetDamping { damping: r.damping, gravity_solid_only: r.gravity_solid_only })?;
        self.sim.advance_until(0.0, u64::MAX, |_| {})?;
        self.apply(&Command::SetDamping { damping: 0.0, gravity_solid_only: false })?;
        self.apply(&Command::SetTime(0.0))
    }

    /// Records the current state hash (a readback).
    pub fn checkpoint(&mut self) -> Result<(), SimError> {
        if self.recorder.is_none() {
            return Ok(());
        }
        let st = self.sim.read_state()?;
        if let Some(r) = &mut self.recorder
            && let Err(e) = r.state_hash(st.steps, st.t, st.hash())
        {
            log::error!("recording stopped: {e}");
            self.recorder = None;
        }
        Ok(())
    }
}

/// What a replay found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ReplayOutcome {
    pub steps: u64,
    pub t: f64,
    pub commands: usize,
    pub hashes_checked: usize,
    /// (step, recorded hash, replayed hash) of every mismatch.
    pub mismatches: Vec<(u64, u64, u64)>,
    pub final_hash: u64,
    /// The container's warnings (truncation, damage), as text.
    pub warnings: Vec<String>,
}

/// The scenario of a recording.
pub fn recorded_scenario(rec: &Recording) -> Result<Scenario, SessionError> {
    Scenario::from_str_named(&rec.header.scenario_text, &rec.source)
        .map_err(|e| SessionError::Scenario { file: rec.source.clone(), detail: e.to_string() })
}

/// Replays `rec` on `backend`: the recorded commands at their steps, comparing state hashes when
/// `verify`. Stops at the last good chunk of a damaged file (its warnings are in the outcome).
pub fn replay(rec: &Recording, backend: BackendKind, verify: bool) -> Result<ReplayOutcome, SessionError> {
    let scenario = recorded_scenario(rec)?;
    let file = rec.source.clone();
    let mut sim = Simulation::new(&scenario, backend).map_err(|source| SessionError::Sim {
        file: file.clone(),
        step: 0,
        source: Box::new(source),
    })?;
    let mut out =
        ReplayOutcome { warnings: rec.warnings.iter().map(|w| w.to_string()).collect(), ..Default::default() };
    for chunk in &rec.chunks {
        // Step forward to the chunk's step.
        while sim.stats().steps < chunk.step {
            let n = (chunk.step - sim.stats().steps).min(u64::from(crate::sim::ADVANCE_CHUNK)) as u32;
            let adv = sim.advance(n, f64::INFINITY).map_err(|source| SessionError::Sim {
                file: file.clone(),
                step: sim.stats().steps,
                source: Box::new(source),
            })?;
            if adv.steps == 0 {
                break;
            }
        }
        match chunk.kind {
            ChunkKind::Commands => {
                let cmds: Vec<Command> = serde_json::from_slice(&chunk.payload).map_err(|e| {
                    SessionError::BadCommands { file: file.clone(), step: chunk.step, detail: e.to_string() }
                })?;
                for c in &cmds {
                    sim.apply(c).map_err(|source| SessionError::Sim {
                        file: file.clone(),
                        step: chunk.step,
                        source: Box::new(source),
                    })?;
                    out.commands += 1;
                }
            }
            ChunkKind::StateHash if verify => {
                let recorded = chunk.payload.get(..8).and_then(|b| b.try_into().ok()).map(u64::from_le_bytes);
                let st = sim.read_state().map_err(|source| SessionError::Sim {
                    file: file.clone(),
                    step: chunk.step,
                    source: Box::new(source),
                })?;
                let got = st.hash();
                out.hashes_checked += 1;
                if recorded != Some(got) {
                    out.mismatches.push((chunk.step, recorded.unwrap_or(0), got));
                }
            }
            _ => {}
        }
    }
    let st = sim.read_state().map_err(|e| SessionError::Sim {
        file: file.clone(),
        step: sim.stats().steps,
        source: Box::new(e),
    })?;
    out.steps = st.steps;
    out.t = st.t;
    out.final_hash = st.hash();
    Ok(out)
}

/// [`replay`] that also shows the replayed states to `on_frame` (`perfuse replay --vtk`): at the first
/// step boundary at or after each multiple of `frame_interval` of simulated time (t ≥ 0, after the
/// commands recorded at that step), then the final state when it is later than the last frame. Without
/// an interval (or with one that is not a positive finite number, which the CLI refuses) it sees only
/// the final state. Stopping at frame times does not change the steps: `Simulation::advance` ends a
/// batch after the step that reaches its time, it does not shorten Δt, so the replay stays the
/// recorded one (and `verify` still holds). A sibling of [`replay`] rather than a change to it, so the
/// plain replay keeps its exact code path; `on_frame`'s error type takes [`SessionError`]s too.
pub fn replay_with<E: From<SessionError>>(
    rec: &Recording,
    backend: BackendKind,
    verify: bool,
    frame_interval: Option<f64>,
    mut on_frame: impl FnMut(&crate::sim::State, &crate::sim::params::Params) -> Result<(), E>,
) -> Result<ReplayOutcome, E> {
    let every = frame_interval.filter(|dt| dt.is_finite() && *dt > 0.0);
    let scenario = recorded_scenario(rec)?;
    let file = rec.source.clone();
    let sim_err = |step: u64| {
        let file = file.clone();
        move |source: SimError| SessionError::Sim { file, step, source: Box::new(source) }
    };
    let mut sim = Simulation::new(&scenario, backend).map_err(sim_err(0))?;
    let mut out =
        ReplayOutcome { warnings: rec.warnings.iter().map(|w| w.to_string()).collect(), ..Default::default() };
    // Frames are due from t = 0 on (not during a recorded relaxation, which runs at t < 0).
    let mut next_frame = if every.is_some() { 0.0 } else { f64::INFINITY };
    let mut last_frame_t = f64::NEG_INFINITY;
    // Shows the state to `on_frame` if a frame is due at the current time.
    let mut frame_if_due = |sim: &mut Simulation, next_frame: &mut f64, last: &mut f64| -> Result<(), E> {
        let t = sim.time();
        if t >= *next_frame - 1e-12 {
            let st = sim.read_state().map_err(sim_err(sim.stats().steps))?;
            on_frame(&st, sim.params())?;
            *last = st.t;
            let dt = every.unwrap_or(f64::INFINITY);
            while *next_frame <= t + 1e-12 {
                *next_frame += dt;
            }
        }
        Ok(())
    };
    for chunk in &rec.chunks {
        // Step forward to the chunk's step, pausing at frame times; the commands of the current step
        // are all applied before its frame is taken (the chunks of one step come one after another).
        while sim.stats().steps < chunk.step {
            frame_if_due(&mut sim, &mut next_frame, &mut last_frame_t)?;
            let n = (chunk.step - sim.stats().steps).min(u64::from(crate::sim::ADVANCE_CHUNK)) as u32;
            let adv = sim.advance(n, next_frame - 1e-12).map_err(sim_err(sim.stats().steps))?;
            if adv.steps == 0 {
                break;
            }
        }
        match chunk.kind {
            ChunkKind::Commands => {
                let cmds: Vec<Command> = serde_json::from_slice(&chunk.payload).map_err(|e| {
                    SessionError::BadCommands { file: file.clone(), step: chunk.step, detail: e.to_string() }
                })?;
                for c in &cmds {
                    sim.apply(c).map_err(sim_err(chunk.step))?;
                    out.commands += 1;
                }
            }
            ChunkKind::StateHash if verify => {
                let recorded = chunk.payload.get(..8).and_then(|b| b.try_into().ok()).map(u64::from_le_bytes);
                let got = sim.read_state().map_err(sim_err(chunk.step))?.hash();
                out.hashes_checked += 1;
                if recorded != Some(got) {
                    out.mismatches.push((chunk.step, recorded.unwrap_or(0), got));
                }
            }
            _ => {}
        }
    }
    frame_if_due(&mut sim, &mut next_frame, &mut last_frame_t)?;
    let st = sim.read_state().map_err(sim_err(sim.stats().steps))?;
    if st.t > last_frame_t + 1e-12 {
        on_frame(&st, sim.params())?;
    }
    out.steps = st.steps;
    out.t = st.t;
    out.final_hash = st.hash();
    Ok(out)
}
