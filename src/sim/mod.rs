//! How a scenario is simulated: one [`Simulation`] API over the back-ends. `cpu` is the rayon reference
//! solver (test oracle, benchmark baseline); the GPU back-end implements the same passes in WGSL.
//!
//! Commands are the only way in ([`Simulation::apply`]); state comes out by readback
//! ([`Simulation::read_state`]). A diverging run (non-finite values, runaway velocity, collapsing Δt)
//! returns [`SimError::Diverged`] and keeps the last good state.

pub mod bed;
pub mod cardio;
pub mod cpu;
pub mod frame;
pub mod ghosts;
pub mod gpu;
pub mod kernels;
pub mod params;
pub mod physiology;
pub mod snapshot;
pub mod state;

use crate::scenario::{Motion, Scenario, ScenarioError, V3};
use params::Params;
use serde::Serialize;
pub use state::{SolidComponent, State};

/// Which term of (2.70) (or our additions) limited a time step.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DtLimit {
    Viscous,
    Sound,
    Force,
    Friction,
    Max,
    Fixed,
}

impl DtLimit {
    pub const ALL: [DtLimit; 6] =
        [DtLimit::Viscous, DtLimit::Sound, DtLimit::Force, DtLimit::Friction, DtLimit::Max, DtLimit::Fixed];
    pub fn name(self) -> &'static str {
        match self {
            DtLimit::Viscous => "viscous",
            DtLimit::Sound => "sound",
            DtLimit::Force => "force",
            DtLimit::Friction => "friction",
            DtLimit::Max => "dt_max",
            DtLimit::Fixed => "fixed",
        }
    }
}

/// What one step did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepInfo {
    pub t: f64,
    pub dt: f32,
    pub limit: DtLimit,
    pub broken_bonds: u64,
}

/// What [`Simulation::advance`] did: enough to keep [`RunStats`] exact without per-step results.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Advance {
    pub steps: u64,
    /// Clock after the last step \[s\].
    pub t: f64,
    /// Smallest and largest Δt of the batch \[s\] (0 when no step was taken).
    pub dt_min: f64,
    pub dt_max: f64,
    /// Steps limited by each criterion, in [`DtLimit::ALL`] order.
    pub limited_by: [u64; 6],
    pub broken_bonds: u64,
}

/// Commands: the only way to change a running simulation (viewer input, replay, scripted tests).
/// Serialisable: a recording is the scenario plus the stream of commands with the step they act at.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub enum Command {
    /// Replace the motion of boundary object `object`; it continues from its current pose.
    SetBoundaryMotion { object: usize, motion: Motion },
    /// Body-force acceleration [m/s²].
    SetGravity(V3),
    /// Velocity damping ζ [1/s] (relaxation), and whether gravity acts on the solid only.
    SetDamping { damping: f64, gravity_solid_only: bool },
    /// Set the simulation clock \[s\] (boundary motions are evaluated at max(t, 0)).
    SetTime(f64),
    /// The suction's valve: `true` (the start state) lets boundaries with a `Prescribed` pressure
    /// show it (SPEC §4.1), outlets prescribe their pressure and sinks remove the liquid in them;
    /// `false` holds all three — the prescribed boundaries show the mirror pressure, the outlets'
    /// buffers are liquid like any other and the sinks remove nothing (a relaxation with
    /// `hold_suction`).
    SetSuction(bool),
    /// Teleport object `object` so that its centre (box centre, sphere centre) is at `position`
    /// (scenario coordinates \[m\]) and hold it there (parking a tool, loading a projectile).
    PlaceObject { object: usize, position: V3 },
    /// Move object `object` in a straight line towards `target` (its centre, scenario coordinates \[m\])
    /// at `speed` [m/s], stopping there: a `Translate` motion from the current pose, so a tool driven
    /// by the mouse is a kinematic body with a bounded, known velocity (SPEC §4.1).
    MoveObject { object: usize, target: V3, speed: f64 },
    /// Replace the flow of emitter `emitter` by the piecewise-linear table `rates` [m³/s] at `times`
    /// \[s\] (increasing, held outside): how the patient model drives the hepatic inlet. Recorded like
    /// every command, so a replay needs no cardiovascular model.
    SetInflow { emitter: usize, times: Vec<f64>, rates: Vec<f64> },
}

/// Checks an inflow table (finite increasing times, finite rates ≥ 0, 1 … FLOW_MAX entries) and
/// converts it to the f32 table both back-ends use.
pub fn inflow_table(times: &[f64], rates: &[f64]) -> Result<cpu::emit::FlowTable, SimError> {
    let bad = |m: String| Err(SimError::BadCommand(format!("SetInflow: {m}")));
    if times.is_empty() || times.len() != rates.len() || times.len() > cpu::emit::FLOW_MAX {
        return bad(format!(
            "{} times for {} rates (give 1 … {} pairs)",
            times.len(),
            rates.len(),
            cpu::emit::FLOW_MAX
        ));
    }
    for k in 0..times.len() {
        if !times[k].is_finite() || (k > 0 && times[k] as f32 <= times[k - 1] as f32) {
            return bad(format!("times[{k}] = {} is not finite and increasing", times[k]));
        }
        if !(rates[k].is_finite() && rates[k] >= 0.0) {
            return bad(format!("rates[{k}] = {} must be finite and ≥ 0", rates[k]));
        }
    }
    Ok(cpu::emit::FlowTable {
        times: times.iter().map(|&t| t as f32).collect(),
        rates: rates.iter().map(|&q| q as f32).collect(),
        period: 0.0,
    })
}

/// Where a boundary object is now (scenario coordinates), for drawing and for tool input.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectPose {
    pub name: String,
    /// The object's shape at its current position.
    pub shape: crate::scenario::Region,
    /// Centre of the shape (box centre or sphere centre) \[m\].
    pub centre: V3,
    pub velocity: V3,
    pub tool: Option<crate::scenario::Tool>,
    /// A bed moulded to the tissue (`Boundary::mould`): its shape only bounds its particles.
    pub moulded: bool,
    /// A moulded bed's particles (scenario coordinates; a bed is static), drawn instead of its shape.
    pub bed: std::sync::Arc<[V3]>,
}

/// Shift of the rest positions that keeps an object in place when its motion changes from one whose
/// displacement is `d_now` to one whose displacement is `d_new` at the same time.
pub(crate) fn reanchor_shift(d_now: V3, d_new: V3) -> glam::Vec3 {
    glam::Vec3::new((d_now[0] - d_new[0]) as f32, (d_now[1] - d_new[1]) as f32, (d_now[2] - d_new[2]) as f32)
}

/// The pose of `object` (rest shape `geom` in simulation coordinates) at time `t`.
pub(crate) fn object_pose(
    params: &Params,
    object: &crate::scenario::BoundaryObject,
    geom: &cpu::forces::ObjectGeom,
    t: f64,
) -> ObjectPose {
    let (d, v) = crate::scenario::motion_at(&object.motion, t);
    let two = params.dim.n() == 2;
    let o = params.origin;
    let world = |p: glam::Vec3| {
        let z = if two { o[2] } else { p.z as f64 + d[2] + o[2] };
        [p.x as f64 + d[0] + o[0], p.y as f64 + d[1] + o[1], z]
    };
    // by the object's shape, not the geometry's kind: a moulded bed's kind is 2 (no shape)
    let (shape, centre) = if matches!(object.shape, crate::scenario::Region::Box { .. }) {
        let (a, b) = (world(geom.a), world(geom.b));
        let c = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0, (a[2] + b[2]) / 2.0];
        (crate::scenario::Region::Box { min: a, max: b }, c)
    } else {
        let c = world(geom.a);
        (crate::scenario::Region::Sphere { centre: c, radius: geom.b.x as f64 }, c)
    };
    ObjectPose {
        name: object.name.clone(),
        shape,
        centre,
        velocity: v,
        tool: object.tool.clone(),
        moulded: object.moulded,
        bed: object.bed.clone(),
    }
}

/// Shift (simulation coordinates) that puts `pose`'s centre at `position`; errors on non-finite input.
pub(crate) fn centre_shift(params: &Params, pose: &ObjectPose, position: V3) -> Result<glam::Vec3, SimError> {
    if !position.iter().all(|x| x.is_finite()) {
        return Err(SimError::BadCommand(format!("object position {position:?} is not finite")));
    }
    let z = if params.dim.n() == 2 { 0.0 } else { (position[2] - pose.centre[2]) as f32 };
    Ok(glam::Vec3::new((position[0] - pose.centre[0]) as f32, (position[1] - pose.centre[1]) as f32, z))
}

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    #[error(
        "simulation diverged at step {step} (t = {t:.6} s), particle {particle}: {reason}; the last good state is kept"
    )]
    Diverged { step: u64, t: f64, particle: String, reason: String },
    #[error("invalid command: {0}")]
    BadCommand(String),
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error("GPU back-end: {0}")]
    Gpu(String),
    #[error(transparent)]
    Snapshot(#[from] snapshot::SnapshotError),
    #[error("out of resources: {0}")]
    Resources(String),
}

/// Which back-end runs the step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BackendKind {
    Cpu,
    Gpu,
}

/// Running statistics of a simulation (for `summary.json`).
#[derive(Clone, Debug, Default, Serialize, serde::Deserialize)]
pub struct RunStats {
    pub steps: u64,
    pub dt_min: f64,
    pub dt_max: f64,
    /// How often each criterion limited Δt, by `DtLimit::name`.
    pub dt_limited_by: std::collections::BTreeMap<String, u64>,
    pub broken_bonds: u64,
}

impl RunStats {
    /// Counts one step taken.
    fn record(&mut self, info: &StepInfo) {
        self.steps += 1;
        self.dt_min = self.dt_min.min(info.dt as f64);
        self.dt_max = self.dt_max.max(info.dt as f64);
        *self.dt_limited_by.entry(info.limit.name().to_string()).or_insert(0) += 1;
        self.broken_bonds += info.broken_bonds;
    }
}

/// What the emitters and sinks have done (issue 7): `summary.json`'s `emitted_volume_m3` and the
/// volume balance initial + emitted − sunk = live, to the particle.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct EmitTotals {
    /// Particles added / removed since t = 0.
    pub emitted: u64,
    pub sunk: u64,
    /// Particles added by each emitter.
    pub per_emitter: Vec<u64>,
    /// Σ m/ρ₀ of the particles added \[m³\].
    pub emitted_volume_m3: f64,
    /// Volume owed by the flows and not yet placed (no free slot) \[m³\].
    pub backlog_m3: f64,
    pub live_liquid: u64,
    pub capacity: u64,
    /// An emitter had volume to place but the liquid capacity was full.
    pub capacity_reached: bool,
}

/// Steps per [`Simulation::advance`] call of the chunked loops (one GPU batch).
pub const ADVANCE_CHUNK: u32 = 64;

enum Engine {
    Cpu(Box<cpu::CpuSolver>),
    Gpu(Box<gpu::GpuSolver>),
}

/// A running simulation of one scenario on one back-end.
pub struct Simulation {
    engine: Engine,
    scenario: Scenario,
    stats: RunStats,
    /// Wall time of GPU batches \[s\] (whole-step timing without timestamp queries).
    gpu_wall_s: f64,
}

impl Simulation {
    pub fn new(scenario: &Scenario, backend: BackendKind) -> Result<Simulation, SimError> {
        Self::build(scenario, crate::scenario::generate(scenario), backend, None)
    }

    /// Like [`Simulation::new`] from particles already generated from `scenario` (and perhaps
    /// rearranged: `perfuse bench --shuffle-liquid` generates the liquid in a random storage order).
    pub fn from_generated(
        scenario: &Scenario,
        generated: crate::scenario::GeneratedParticles,
        backend: BackendKind,
    ) -> Result<Simulation, SimError> {
        Self::build(scenario, generated, backend, None)
    }

    /// Like [`Simulation::new`], with the GPU back-end on an existing device (the viewer shares its
    /// device between simulation and renderer). `gpu = None` selects the CPU back-end.
    pub fn with_gpu(scenario: &Scenario, gpu: Option<gpu::GpuContext>) -> Result<Simulation, SimError> {
        match gpu {
            Some(ctx) => Self::build(scenario, crate::scenario::generate(scenario), BackendKind::Gpu, Some(ctx)),
            None => Self::build(scenario, crate::scenario::generate(scenario), BackendKind::Cpu, None),
        }
    }

    fn build(
        scenario: &Scenario,
        generated: crate::scenario::GeneratedParticles,
        backend: BackendKind,
        ctx: Option<gpu::GpuContext>,
    ) -> Result<Simulation, SimError> {
        scenario.validate("(scenario)")?;
        if generated.liquid_capacity < generated.liquid.pos.len() {
            return Err(SimError::Scenario(ScenarioError::Invalid {
                path: "(scenario)".into(),
                field: "liquid_capacity".into(),
                problem: format!(
                    "{} is below the {} liquid particles generated",
                    generated.liquid_capacity,
                    generated.liquid.pos.len()
                ),
                fix: "raise it or leave it out (default: the initial liquid + 20 000 with emitters)".into(),
            }));
        }
        let params = Params::new(scenario, &generated);
        let engine = match (backend, ctx) {
            (BackendKind::Cpu, _) => Engine::Cpu(Box::new(cpu::CpuSolver::new(params, &generated)?)),
            (BackendKind::Gpu, None) => Engine::Gpu(Box::new(gpu::GpuSolver::new(params, &generated)?)),
            (BackendKind::Gpu, Some(ctx)) => {
                Engine::Gpu(Box::new(gpu::GpuSolver::with_context(ctx, params, &generated)?))
            }
        };
        Ok(Simulation {
            engine,
            scenario: scenario.clone(),
            stats: RunStats { dt_min: f64::INFINITY, ..Default::default() },
            gpu_wall_s: 0.0,
        })
    }

    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    pub fn params(&self) -> &Params {
        match &self.engine {
            Engine::Cpu(c) => &c.params,
            Engine::Gpu(g) => &g.params,
        }
    }

    pub fn time(&self) -> f64 {
        match &self.engine {
            Engine::Cpu(c) => c.st.t,
            Engine::Gpu(g) => g.time(),
        }
    }

    pub fn stats(&self) -> &RunStats {
        &self.stats
    }

    /// Advances one time step.
    pub fn step(&mut self) -> Result<StepInfo, SimError> {
        let info = match &mut self.engine {
            Engine::Cpu(c) => c.step()?,
            Engine::Gpu(g) => {
                let start = std::time::Instant::now();
                let info = g.step();
                self.gpu_wall_s += start.elapsed().as_secs_f64();
                info?
            }
        };
        self.stats.record(&info);
        Ok(info)
    }

    /// Takes up to `max_steps` steps, stopping after the first step whose end time reaches `t_end`
    /// (none if the clock is already there). The CPU steps in batches with one copy of the last good
    /// state each (`CpuSolver::advance`); the GPU encodes the steps in
    /// batches with one readback each (`GpuSolver::advance`). [`RunStats`] count every step taken, also
    /// when a later one diverges (then `SimError::Diverged` names the diverging step and the last good
    /// state is kept, as with [`Simulation::step`]).
    pub fn advance(&mut self, max_steps: u32, t_end: f64) -> Result<Advance, SimError> {
        let mut adv = Advance { t: self.time(), ..Default::default() };
        match &mut self.engine {
            Engine::Cpu(c) => {
                let stats = &mut self.stats;
                c.advance(u64::from(max_steps), t_end, |info| {
                    stats.record(info);
                    adv.steps += 1;
                    let dt = info.dt as f64;
                    if adv.steps == 1 {
                        (adv.dt_min, adv.dt_max) = (dt, dt);
                    }
                    adv.dt_min = adv.dt_min.min(dt);
                    adv.dt_max = adv.dt_max.max(dt);
                    if let Some(i) = DtLimit::ALL.iter().position(|l| *l == info.limit) {
                        adv.limited_by[i] += 1;
                    }
                    adv.broken_bonds += info.broken_bonds;
                    adv.t = info.t;
                })?;
            }
            Engine::Gpu(g) => {
                let mut acc = gpu::BatchTotals::default();
                let r = g.advance(u64::from(max_steps), t_end, &mut acc);
                self.gpu_wall_s += acc.wall_s;
                adv = Advance {
                    steps: acc.steps,
                    t: g.time(),
                    dt_min: acc.dt_min as f64,
                    dt_max: acc.dt_max as f64,
                    limited_by: acc.limited_by,
                    broken_bonds: acc.broken_bonds,
                };
                let s = &mut self.stats;
                if acc.steps > 0 {
                    s.steps += acc.steps;
                    s.dt_min = s.dt_min.min(adv.dt_min);
                    s.dt_max = s.dt_max.max(adv.dt_max);
                    for (l, n) in DtLimit::ALL.iter().zip(acc.limited_by) {
                        if n > 0 {
                            *s.dt_limited_by.entry(l.name().to_string()).or_insert(0) += n;
                        }
                    }
                    s.broken_bonds += acc.broken_bonds;
                }
                r?;
            }
        }
        Ok(adv)
    }

    /// Steps until the clock reaches `t_end` (or `max_steps` steps), in chunks of up to
    /// [`ADVANCE_CHUNK`] steps, calling `progress(t)` after each chunk.
    pub fn advance_until(
        &mut self,
        t_end: f64,
        max_steps: u64,
        mut progress: impl FnMut(f64),
    ) -> Result<u64, SimError> {
        let mut n = 0;
        while self.time() < t_end && n < max_steps {
            let chunk = (max_steps - n).min(u64::from(ADVANCE_CHUNK)) as u32;
            let adv = self.advance(chunk, t_end)?;
            if adv.steps == 0 {
                break;
            }
            progress(adv.t);
            n += adv.steps;
        }
        Ok(n)
    }

    /// Runs the scenario's damped relaxation (SPEC §7.5), if any, ending with the clock at t = 0.
    pub fn relax(&mut self, mut progress: impl FnMut(f64)) -> Result<(), SimError> {
        let Some(r) = self.scenario.relaxation.clone() else { return Ok(()) };
        if r.duration <= 0.0 {
            return Ok(());
        }
        for c in r.start_commands() {
            self.apply(&c)?;
        }
        self.advance_until(0.0, u64::MAX, &mut progress)?;
        for c in r.end_commands() {
            self.apply(&c)?;
        }
        Ok(())
    }

    pub fn apply(&mut self, cmd: &Command) -> Result<(), SimError> {
        if let Command::MoveObject { object, target, speed } = cmd {
            return self.apply(&self.move_command(*object, *target, *speed)?);
        }
        match &mut self.engine {
            Engine::Cpu(c) => c.apply(cmd),
            Engine::Gpu(g) => g.apply(cmd),
        }
    }

    /// `MoveObject` as the `SetBoundaryMotion` it stands for: translate at `speed` towards `target`
    /// from now until arrival (static when already there).
    fn move_command(&self, object: usize, target: V3, speed: f64) -> Result<Command, SimError> {
        if !(speed.is_finite() && speed > 0.0) {
            return Err(SimError::BadCommand(format!("MoveObject speed {speed} m/s must be finite and > 0")));
        }
        if !target.iter().all(|x| x.is_finite()) {
            return Err(SimError::BadCommand(format!("MoveObject target {target:?} is not finite")));
        }
        let poses = self.object_poses();
        let pose = poses.get(object).ok_or_else(|| SimError::BadCommand(format!("no boundary object #{object}")))?;
        let three = self.params().dim.n() == 3;
        let mut delta = [target[0] - pose.centre[0], target[1] - pose.centre[1], target[2] - pose.centre[2]];
        if !three {
            delta[2] = 0.0;
        }
        let dist = (delta[0] * delta[0] + delta[1] * delta[1] + delta[2] * delta[2]).sqrt();
        let t = self.time();
        // Below a thousandth of Δx the object stays where it is.
        if dist <= 1e-3 * f64::from(self.params().k_solid.h.min(self.params().k_liquid.h)) {
            return Ok(Command::SetBoundaryMotion { object, motion: Motion::Static });
        }
        let velocity = [delta[0] / dist * speed, delta[1] / dist * speed, delta[2] / dist * speed];
        // Motions are evaluated at max(t, 0); during relaxation (t < 0) the move starts at 0.
        let start = t.max(0.0);
        Ok(Command::SetBoundaryMotion {
            object,
            motion: Motion::Translate { velocity, start, stop: Some(start + dist / speed) },
        })
    }

    /// Particle counts (liquid, solid) a render buffer set must hold: the liquid capacity (emitters
    /// add particles), the solid count.
    pub fn frame_counts(&self) -> (u32, u32) {
        match &self.engine {
            Engine::Cpu(c) => (c.st.emit.capacity.max(c.st.liquid.x.len()) as u32, c.st.solid.x.len() as u32),
            Engine::Gpu(g) => g.frame_capacity(),
        }
    }

    /// Live (liquid, solid) particle counts.
    pub fn particle_counts(&self) -> (u32, u32) {
        match &self.engine {
            Engine::Cpu(c) => (c.st.liquid.x.len() as u32, c.st.solid.x.len() as u32),
            Engine::Gpu(g) => g.particle_counts(),
        }
    }

    /// Emitter and sink totals (on the GPU back-end one small readback when there are emitters).
    pub fn emit_totals(&self) -> Result<EmitTotals, SimError> {
        match &self.engine {
            Engine::Cpu(c) => Ok(c.emit_totals()),
            Engine::Gpu(g) => g.emit_totals(),
        }
    }

    /// Indices of the scenario's emitters whose flow is the patient's hepatic flow.
    pub fn hepatic_emitters(&self) -> Vec<usize> {
        let hepatic = |e: &crate::scenario::Emitter| matches!(e.flow, crate::scenario::Flow::Hepatic);
        self.scenario.emitters.iter().enumerate().filter(|(_, e)| hepatic(e)).map(|(k, _)| k).collect()
    }

    /// Fills render buffer set `frame` with the current state and returns what goes with it. On the
    /// GPU back-end `frame` must live on the simulation's device (see [`Simulation::with_gpu`]); the
    /// copy is queued on the GPU, nothing is read back. `queue` is used by the CPU back-end.
    pub fn publish(&self, frame: &frame::FrameBuffers, queue: &wgpu::Queue) -> Result<frame::FrameInfo, SimError> {
        match &self.engine {
            Engine::Cpu(c) => c.publish(frame, queue),
            Engine::Gpu(g) => g.publish(frame).map_err(|e| SimError::Gpu(e.to_string()))?,
        }
        Ok(frame::FrameInfo {
            n_liquid: self.particle_counts().0,
            t: self.time(),
            steps: self.stats.steps,
            objects: self.object_poses(),
            origin: self.params().origin,
        })
    }

    /// The GPU device the simulation runs on, if it runs on one.
    pub fn gpu_context(&self) -> Option<&gpu::GpuContext> {
        match &self.engine {
            Engine::Cpu(_) => None,
            Engine::Gpu(g) => Some(&g.ctx),
        }
    }

    /// Current pose of every boundary object (scenario coordinates).
    pub fn object_poses(&self) -> Vec<ObjectPose> {
        match &self.engine {
            Engine::Cpu(c) => c.object_poses(),
            Engine::Gpu(g) => g.object_poses(),
        }
    }

    /// GPU back-end: time the passes per entry point instead of per family from now on (`perfuse bench
    /// --entry-points`); the CPU's timers are per family only.
    pub fn time_entry_points(&mut self, by_entry: bool) {
        if let Engine::Gpu(g) = &mut self.engine {
            g.time_entry_points(by_entry);
        }
    }

    /// Accumulated wall time per pass family (GPU: or entry point) \[s\], sorted by name.
    pub fn pass_times(&self) -> Vec<(String, f64)> {
        match &self.engine {
            Engine::Cpu(c) => c.timers.totals.iter().map(|(k, v)| (k.to_string(), v.as_secs_f64())).collect(),
            // Timestamp queries per pass family, else the whole step's wall time.
            Engine::Gpu(g) => g.pass_times().unwrap_or_else(|| vec![(String::from("step"), self.gpu_wall_s)]),
        }
    }

    /// GPU back-end: host seconds spent in the per-batch error scopes (push + pop) and the batches
    /// run, so that `perfuse bench` can report what catching GPU errors per batch costs. CPU: `None`.
    pub fn error_scope_cost(&self) -> Option<(f64, u64)> {
        match &self.engine {
            Engine::Cpu(_) => None,
            Engine::Gpu(g) => Some(g.error_scope_cost()),
        }
    }

    /// Device or host memory used by particle storage \[bytes\].
    pub fn memory_bytes(&self) -> usize {
        match &self.engine {
            Engine::Cpu(c) => c.memory_bytes(),
            Engine::Gpu(g) => g.memory_bytes(),
        }
    }

    /// Name of the back-end and, for the GPU, its adapter.
    pub fn backend_name(&self) -> String {
        match &self.engine {
            Engine::Cpu(_) => format!("cpu (rayon, {} threads)", rayon::current_num_threads()),
            Engine::Gpu(g) => format!("gpu ({}, {:?})", g.ctx.info.name, g.ctx.info.backend),
        }
    }

    /// The GPU adapter with its driver ("" on the CPU): with [`Simulation::backend_name`], what decides
    /// a GPU run's rounding.
    pub fn adapter_name(&self) -> String {
        match &self.engine {
            Engine::Cpu(_) => String::new(),
            Engine::Gpu(g) => {
                let i = &g.ctx.info;
                format!("{} ({} {})", i.name, i.driver, i.driver_info).trim_end_matches(" ( )").to_string()
            }
        }
    }

    /// A keyframe of everything that evolves (a readback on the GPU): see [`snapshot`].
    pub fn snapshot(&mut self) -> Result<snapshot::Snapshot, SimError> {
        let data = match &self.engine {
            Engine::Cpu(c) => snapshot::EngineSnapshot::Cpu(Box::new(c.snapshot())),
            Engine::Gpu(g) => snapshot::EngineSnapshot::Gpu(Box::new(g.snapshot()?)),
        };
        Ok(snapshot::Snapshot {
            layout: snapshot::SNAPSHOT_LAYOUT,
            engine: self.backend_name(),
            t: self.time(),
            steps: self.stats.steps,
            stats: self.stats.clone(),
            data,
        })
    }

    /// Restores a keyframe taken from a simulation of the same scenario on the same back-end kind;
    /// stepping on then gives the states the original run gave (bit for bit on the same adapter). On
    /// error the simulation is unchanged, except after a GPU failure mid-restore.
    pub fn restore(&mut self, snap: snapshot::Snapshot) -> Result<(), SimError> {
        use snapshot::{EngineSnapshot, SnapshotError};
        let stats = snap.stats;
        match (&mut self.engine, snap.data) {
            (Engine::Cpu(c), EngineSnapshot::Cpu(s)) => c.restore(*s)?,
            (Engine::Gpu(g), EngineSnapshot::Gpu(s)) => g.restore_snapshot(*s)?,
            (engine, data) => {
                let want = if matches!(engine, Engine::Cpu(_)) { "CPU" } else { "GPU" };
                return Err(SnapshotError::Backend { found: data.kind(), want }.into());
            }
        }
        self.stats = stats;
        Ok(())
    }

    pub fn read_state(&mut self) -> Result<State, SimError> {
        match &self.engine {
            Engine::Cpu(c) => Ok(c.read_state()),
            Engine::Gpu(g) => g.read_state(),
        }
    }
}
