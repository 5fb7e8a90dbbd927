//! Recording and replaying sessions on top of the container (`format`): a [`Recorder`] writes the
//! scenario (as RON, mesh paths made absolute) into the header, every command applied to the
//! simulation as a `Commands` chunk stamped with the step it acts before, `StateHash` chunks, and
//! `Keyframe` chunks (a [`Keyframe`]: the simulation's [`Snapshot`] and the patient's cardiovascular
//! state). The [`Player`] rebuilds the simulation from the header and feeds it the same commands at
//! the same steps — the same code path as live use — checking the hashes on the way (`perfuse replay
//! --verify`); it seeks by restoring the nearest keyframe before the target and stepping forward,
//! and [`Player::take_over`] hands its simulation to live use, optionally recording a branch that
//! names its parent and starts with a keyframe. On one adapter a replay is bit-identical (DESIGN:
//! determinism), and so is a seek.
//!
//! Chunk time stamps must not decrease, but the clock runs from −duration to 0 during the scenario's
//! relaxation: the recorder stamps chunks with the clock clamped to its running maximum, so the
//! relaxation sits at t = 0 on the timeline (steps still order it).

use super::format::{ChunkKind, Header, Parent, Recording, RecordingWriter, ReplayError};
use crate::scenario::{Generator, Scenario};
use crate::sim::physiology::Patient;
use crate::sim::snapshot::{Snapshot, SnapshotError};
use crate::sim::{BackendKind, Command, SimError, Simulation};
use std::path::Path;

/// Stepping wall time between keyframes of a live recording: a seek replays at most this much.
pub const KEYFRAME_EVERY: std::time::Duration = std::time::Duration::from_secs(10);
/// Wall time between state hashes of a live recording (`perfuse replay --verify` checks them).
pub const HASH_EVERY: std::time::Duration = std::time::Duration::from_secs(2);

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
    #[error(
        "recording {file} is a branch that starts at step {step} from a keyframe that cannot be used here: {source}. \
         Replay it with the back-end that recorded it ({backend}), or replay its parent {parent}"
    )]
    BranchStart { file: String, step: u64, backend: String, parent: String, source: Box<SimError> },
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

/// What a `Keyframe` chunk holds: the simulation's snapshot and, in sessions with a patient, the
/// cardiovascular model's state (so that a take-over continues the same patient).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Keyframe {
    pub sim: Snapshot,
    pub patient: Option<Patient>,
}

impl Keyframe {
    pub fn encode(&self) -> Vec<u8> {
        postcard::to_stdvec(self).unwrap_or_default()
    }

    pub fn decode(bytes: &[u8]) -> Result<Keyframe, SnapshotError> {
        // `sim` is the first field, so the encoding leads with its layout.
        crate::sim::snapshot::decode_checked(bytes)
    }
}

/// Writes a session: header, commands, state hashes, keyframes.
pub struct Recorder {
    writer: RecordingWriter<std::fs::File>,
    /// Largest time stamp written (chunk stamps never decrease; see the module docs).
    last_t: f64,
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
        Self::with_header(path, &header)
    }

    /// Starts a branch of `parent` taken over at `step`, `t`: the parent's scenario text, its file and
    /// header hash in the header. Write a keyframe first ([`RecordedSimulation::keyframe`]): a branch
    /// replays from it.
    pub fn create_branch(
        path: &Path,
        parent: &Recording,
        backend: &str,
        adapter: &str,
        step: u64,
        t: f64,
    ) -> Result<Recorder, ReplayError> {
        let header = Header::new(
            concat!("perfuse ", env!("CARGO_PKG_VERSION")),
            backend,
            adapter,
            parent.header.scenario_name.clone(),
            parent.header.scenario_text.clone(),
        )
        .with_parent(Parent {
            file: parent.source.clone(),
            hash_of_parent_header: parent.header.header_hash(),
            t_s: t,
            step,
        });
        Self::with_header(path, &header)
    }

    fn with_header(path: &Path, header: &Header) -> Result<Recorder, ReplayError> {
        Ok(Recorder { writer: RecordingWriter::create(path, header)?, last_t: f64::NEG_INFINITY })
    }

    fn stamp(&mut self, t: f64) -> f64 {
        self.last_t = self.last_t.max(t);
        self.last_t
    }

    /// Records `cmd`, applied after `step` steps at time `t`.
    pub fn command(&mut self, step: u64, t: f64, cmd: &Command) -> Result<(), ReplayError> {
        let payload = serde_json::to_vec(&[cmd]).unwrap_or_default();
        let t = self.stamp(t);
        self.writer.write_chunk(ChunkKind::Commands, t, step, &payload)
    }

    /// Records the state hash after `step` steps.
    pub fn state_hash(&mut self, step: u64, t: f64, hash: u64) -> Result<(), ReplayError> {
        let t = self.stamp(t);
        self.writer.write_chunk(ChunkKind::StateHash, t, step, &hash.to_le_bytes())
    }

    /// Records a keyframe taken after `step` steps (compressed by the container when it pays).
    pub fn keyframe(&mut self, step: u64, t: f64, keyframe: &Keyframe) -> Result<(), ReplayError> {
        let t = self.stamp(t);
        self.writer.write_chunk(ChunkKind::Keyframe, t, step, &keyframe.encode())
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
        for c in r.start_commands() {
            self.apply(&c)?;
        }
        self.sim.advance_until(0.0, u64::MAX, |_| {})?;
        for c in r.end_commands() {
            self.apply(&c)?;
        }
        Ok(())
    }

    /// Records the current state hash (a readback).
    pub fn checkpoint(&mut self) -> Result<(), SimError> {
        if self.recorder.is_none() {
            return Ok(());
        }
        let st = self.sim.read_state()?;
        self.write(|r| r.state_hash(st.steps, st.t, st.hash()));
        Ok(())
    }

    /// Records a keyframe of the current state (and `patient`), followed by its state hash: a
    /// readback of the whole state; the recording's size per keyframe is about the particle storage.
    pub fn keyframe(&mut self, patient: Option<&Patient>) -> Result<(), SimError> {
        if self.recorder.is_none() {
            return Ok(());
        }
        let snap = self.sim.snapshot()?;
        let hash = self.sim.read_state()?.hash();
        let (step, t) = (snap.steps, snap.t);
        let kf = Keyframe { sim: snap, patient: patient.cloned() };
        self.write(|r| r.keyframe(step, t, &kf).and_then(|()| r.state_hash(step, t, hash)));
        Ok(())
    }

    /// Runs `f` on the recorder; a failed write ends the recording (logged), not the session.
    fn write(&mut self, f: impl FnOnce(&mut Recorder) -> Result<(), ReplayError>) {
        if let Some(r) = &mut self.recorder
            && let Err(e) = f(r)
        {
            log::error!("recording stopped: {e}");
            self.recorder = None;
        }
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
    /// The container's warnings (truncation, damage), as text, and the player's (unusable keyframes).
    pub warnings: Vec<String>,
    /// Keyframes restored (seeks, the start of a branch).
    pub keyframes_restored: usize,
}

/// The scenario of a recording.
pub fn recorded_scenario(rec: &Recording) -> Result<Scenario, SessionError> {
    Scenario::from_str_named(&rec.header.scenario_text, &rec.source)
        .map_err(|e| SessionError::Scenario { file: rec.source.clone(), detail: e.to_string() })
}

/// Replays `rec` on `backend` to its end: the recorded commands at their steps, comparing state
/// hashes when `verify`. Stops at the last good chunk of a damaged file (its warnings are in the
/// outcome).
pub fn replay(rec: &Recording, backend: BackendKind, verify: bool) -> Result<ReplayOutcome, SessionError> {
    let mut player = Player::new(rec.clone(), backend, verify)?;
    player.play_to_end()?;
    player.finish()
}

/// Plays a recording: the simulation rebuilt from its scenario, fed the recorded commands at their
/// steps; seeks through keyframes; hands over to live use ([`Player::take_over`]).
pub struct Player {
    rec: Recording,
    sim: Simulation,
    /// Index of the next chunk to act on.
    next: usize,
    /// The state after the build (or the branch's first keyframe): where a seek before every
    /// keyframe restarts.
    start: Snapshot,
    start_chunk: usize,
    verify: bool,
    /// The patient of the last keyframe restored (take-over continues it).
    patient: Option<Patient>,
    out: ReplayOutcome,
}

impl Player {
    /// Builds the recorded scenario on `backend`; a recording whose first chunk is a keyframe (a
    /// take-over branch) starts from it: the commands that led there are in its parent.
    pub fn new(rec: Recording, backend: BackendKind, verify: bool) -> Result<Player, SessionError> {
        let scenario = recorded_scenario(&rec)?;
        let sim = Simulation::new(&scenario, backend).map_err(|e| sim_err(&rec, 0, e))?;
        Self::with_simulation(rec, sim, verify)
    }

    /// As [`Player::new`], on a simulation built by the caller from [`recorded_scenario`] (the viewer
    /// builds it on its own device).
    pub fn with_simulation(rec: Recording, mut sim: Simulation, verify: bool) -> Result<Player, SessionError> {
        let out =
            ReplayOutcome { warnings: rec.warnings.iter().map(|w| w.to_string()).collect(), ..Default::default() };
        let mut start_chunk = 0;
        let mut patient = None;
        if let Some(first) = rec.chunks.first().filter(|c| c.kind == ChunkKind::Keyframe) {
            let parent = rec.header.parent.as_ref().map_or_else(|| "(none named)".to_string(), |p| p.file.clone());
            let branch_err = |source: SimError| SessionError::BranchStart {
                file: rec.source.clone(),
                step: first.step,
                backend: rec.header.backend.clone(),
                parent: parent.clone(),
                source: Box::new(source),
            };
            let kf = Keyframe::decode(&first.payload).map_err(|e| branch_err(e.into()))?;
            sim.restore(kf.sim).map_err(branch_err)?;
            patient = kf.patient;
            start_chunk = 1;
        }
        let start = sim.snapshot().map_err(|e| sim_err(&rec, 0, e))?;
        let mut p = Player { rec, sim, next: start_chunk, start, start_chunk, verify, patient, out };
        p.out.keyframes_restored = start_chunk;
        Ok(p)
    }

    pub fn recording(&self) -> &Recording {
        &self.rec
    }

    pub fn simulation(&self) -> &Simulation {
        &self.sim
    }

    /// The simulation, for readbacks and publishing frames (commands go through the recording).
    pub fn simulation_mut(&mut self) -> &mut Simulation {
        &mut self.sim
    }

    /// The patient restored with the last keyframe, if the recording has one.
    pub fn patient(&self) -> Option<&Patient> {
        self.patient.as_ref()
    }

    /// Step and time stamp of the recording's last chunk: where the replay ends.
    pub fn end(&self) -> (u64, f64) {
        self.rec.chunks.last().map_or((self.start.steps, self.start.t.max(0.0)), |c| (c.step, c.t_s))
    }

    /// Every chunk has been acted on and the simulation stands at the last one's step.
    pub fn at_end(&self) -> bool {
        self.next >= self.rec.chunks.len() && self.sim.stats().steps >= self.end().0
    }

    /// Steps taken so far (the recording's step count).
    pub fn steps(&self) -> u64 {
        self.sim.stats().steps
    }

    /// Acts on every chunk stamped at or before the current step.
    fn process_due(&mut self) -> Result<(), SessionError> {
        while let Some(chunk) = self.rec.chunks.get(self.next) {
            let step = self.sim.stats().steps;
            if chunk.step > step {
                break;
            }
            self.next += 1;
            match chunk.kind {
                ChunkKind::Commands => {
                    let cmds: Vec<Command> = serde_json::from_slice(&chunk.payload).map_err(|e| {
                        SessionError::BadCommands { file: self.rec.source.clone(), step, detail: e.to_string() }
                    })?;
                    for c in &cmds {
                        self.sim.apply(c).map_err(|e| sim_err(&self.rec, step, e))?;
                        self.out.commands += 1;
                    }
                }
                ChunkKind::StateHash if self.verify => {
                    let recorded = chunk.payload.get(..8).and_then(|b| b.try_into().ok()).map(u64::from_le_bytes);
                    let got = self.sim.read_state().map_err(|e| sim_err(&self.rec, step, e))?.hash();
                    self.out.hashes_checked += 1;
                    if recorded != Some(got) {
                        self.out.mismatches.push((step, recorded.unwrap_or(0), got));
                    }
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// Acts on the due chunks, then takes up to `max_steps` steps, never past the next chunk's step
    /// or the recording's end; returns the steps taken (0 at the end).
    pub fn step_forward(&mut self, max_steps: u32) -> Result<u64, SessionError> {
        self.process_due()?;
        let taken = self.advance_within(u64::from(max_steps), u64::MAX, f64::INFINITY)?;
        if taken > 0 {
            self.process_due()?;
        }
        Ok(taken)
    }

    /// Takes up to `max_steps` steps, stopping after the first whose end time reaches `t_end`, never
    /// past the next chunk's step, `until` or the recording's end; returns the steps taken (0 when
    /// there is nothing to take). The one place the player steps the simulation.
    fn advance_within(&mut self, max_steps: u64, until: u64, t_end: f64) -> Result<u64, SessionError> {
        let now = self.sim.stats().steps;
        let limit = self.rec.chunks.get(self.next).map_or(self.end().0, |c| c.step).min(until);
        let n = limit.saturating_sub(now).min(max_steps) as u32;
        if n == 0 {
            return Ok(0);
        }
        Ok(self.sim.advance(n, t_end).map_err(|e| sim_err(&self.rec, now, e))?.steps)
    }

    /// Plays from the current position to `step` (or the recording's end), acting on every chunk
    /// stamped at or before it.
    pub fn play_to_step(&mut self, step: u64) -> Result<(), SessionError> {
        loop {
            self.process_due()?;
            if self.sim.stats().steps >= step || self.at_end() {
                return Ok(());
            }
            if self.advance_within(u64::from(crate::sim::ADVANCE_CHUNK), step, f64::INFINITY)? == 0 {
                return Ok(());
            }
        }
    }

    /// Plays to the end of the recording.
    pub fn play_to_end(&mut self) -> Result<(), SessionError> {
        self.play_to_step(self.end().0)
    }

    /// Plays from the current position until every chunk stamped at or before `t` has been acted on
    /// and the clock has reached `t` (or the recording's end).
    pub fn play_to_time(&mut self, t: f64) -> Result<(), SessionError> {
        // the last chunk stamped ≤ t fixes the least step; the clock then decides
        let due = self.rec.chunks.partition_point(|c| c.t_s <= t);
        if let Some(c) = due.checked_sub(1).and_then(|k| self.rec.chunks.get(k)) {
            self.play_to_step(c.step)?;
        }
        while self.sim.time() < t && !self.at_end() {
            self.process_due()?;
            if self.advance_within(u64::from(crate::sim::ADVANCE_CHUNK), u64::MAX, t)? == 0 {
                break;
            }
        }
        self.process_due()
    }

    /// Goes to `step`: restores the latest usable keyframe at or before it (or the start) unless
    /// playing on from the current position is shorter, then plays to it. Equal, on the adapter that
    /// recorded it, to a straight replay to `step`.
    pub fn seek_step(&mut self, step: u64) -> Result<(), SessionError> {
        let now = self.sim.stats().steps;
        let end = self.rec.chunks.partition_point(|c| c.step <= step);
        self.jump_before(end, now <= step)?;
        self.play_to_step(step)
    }

    /// Goes to time `t` (as [`Player::play_to_time`] from the latest usable keyframe at or before it).
    pub fn seek_time(&mut self, t: f64) -> Result<(), SessionError> {
        let ahead = self.sim.time() <= t;
        let end = self.rec.chunks.partition_point(|c| c.t_s <= t);
        self.jump_before(end, ahead)?;
        self.play_to_time(t)
    }

    /// Restores the latest usable keyframe among chunks `[start_chunk, end)`, unless `ahead` (the
    /// target lies ahead of the current position) and that keyframe is not past the current position.
    /// Unusable keyframes (damaged, another back-end) are skipped with a warning.
    fn jump_before(&mut self, end: usize, ahead: bool) -> Result<(), SessionError> {
        let mut k = end;
        while k > self.start_chunk {
            k -= 1;
            let chunk = &self.rec.chunks[k];
            if chunk.kind != ChunkKind::Keyframe {
                continue;
            }
            if ahead && k < self.next {
                return Ok(()); // playing on from here is shorter
            }
            let restored = Keyframe::decode(&chunk.payload)
                .map_err(SimError::from)
                .and_then(|kf| self.sim.restore(kf.sim).map(|()| kf.patient));
            match restored {
                Ok(patient) => {
                    self.patient = patient;
                    self.next = k + 1;
                    self.out.keyframes_restored += 1;
                    return Ok(());
                }
                Err(e) => {
                    let w = format!("keyframe at step {} not used: {e}", chunk.step);
                    if !self.out.warnings.contains(&w) {
                        log::warn!("{w}");
                        self.out.warnings.push(w);
                    }
                }
            }
        }
        if ahead {
            return Ok(());
        }
        self.sim.restore(self.start.clone()).map_err(|e| sim_err(&self.rec, 0, e))?;
        self.next = self.start_chunk;
        Ok(())
    }

    /// The outcome so far, with the final state's hash (a readback).
    pub fn finish(mut self) -> Result<ReplayOutcome, SessionError> {
        let st = self.sim.read_state().map_err(|e| sim_err(&self.rec, self.sim.stats().steps, e))?;
        self.out.steps = st.steps;
        self.out.t = st.t;
        self.out.final_hash = st.hash();
        Ok(self.out)
    }

    /// What the replay found so far.
    pub fn outcome(&self) -> &ReplayOutcome {
        &self.out
    }

    /// Stops replaying and continues live from the current state: returns the simulation (commands
    /// due at this step already applied) and the patient of the last keyframe restored. With `branch`
    /// a new recording starts there that names this one as its parent and begins with a keyframe
    /// (`backend`/`adapter` as for [`Recorder::create`]).
    pub fn take_over(
        mut self,
        branch: Option<(&Path, &str, &str)>,
    ) -> Result<(RecordedSimulation, Option<Patient>), SessionError> {
        self.process_due()?;
        let (step, t) = (self.sim.stats().steps, self.sim.time());
        let recorder = match branch {
            Some((path, backend, adapter)) => {
                Some(Recorder::create_branch(path, &self.rec, backend, adapter, step, t)?)
            }
            None => None,
        };
        let mut rs = RecordedSimulation { sim: self.sim, recorder };
        rs.keyframe(self.patient.as_ref()).map_err(|e| sim_err(&self.rec, step, e))?;
        Ok((rs, self.patient))
    }
}

fn sim_err(rec: &Recording, step: u64, e: SimError) -> SessionError {
    SessionError::Sim { file: rec.source.clone(), step, source: Box::new(e) }
}

/// [`replay`], showing the state to `on_frame` at the first step at or after every multiple of
/// `frame_interval` seconds of simulated time from t = 0 (after the commands recorded at that step;
/// not during a recorded relaxation, which runs at t < 0), and the final state. Without an interval
/// (or with one that is not a positive finite number, which the CLI refuses) it sees only the final
/// state. Stopping at frame times does not change the steps: `Simulation::advance` ends a batch after
/// the step that reaches its time, it does not shorten Δt, so the replay stays the recorded one (and
/// `verify` still holds). `on_frame`'s error type takes [`SessionError`]s too.
pub fn replay_with<E: From<SessionError>>(
    rec: &Recording,
    backend: BackendKind,
    verify: bool,
    frame_interval: Option<f64>,
    mut on_frame: impl FnMut(&crate::sim::State, &crate::sim::params::Params) -> Result<(), E>,
) -> Result<ReplayOutcome, E> {
    let mut player = Player::new(rec.clone(), backend, verify)?;
    let mut last_t = f64::NEG_INFINITY;
    let mut show = |player: &mut Player, last_t: &mut f64| -> Result<(), E> {
        let steps = player.steps();
        let st = player.sim.read_state().map_err(|e| sim_err(&player.rec, steps, e))?;
        if st.t > *last_t + 1e-12 {
            on_frame(&st, player.sim.params())?;
            *last_t = st.t;
        }
        Ok(())
    };
    if let Some(dt) = frame_interval.filter(|dt| dt.is_finite() && *dt > 0.0) {
        let mut k = 0u64;
        while !player.at_end() {
            let t = k as f64 * dt;
            player.play_to_time(t)?;
            if player.sim.time() < t - 1e-12 {
                break; // the recording ended before the frame's time
            }
            show(&mut player, &mut last_t)?;
            // the next frame time after the clock (a step may cross several)
            k = ((player.sim.time() + 1e-12) / dt).floor().max(k as f64) as u64 + 1;
        }
    }
    player.play_to_end()?;
    show(&mut player, &mut last_t)?;
    Ok(player.finish()?)
}
