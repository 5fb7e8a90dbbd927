//! The `perfuse` command line: headless runs and validation.

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand, ValueEnum};
use perfuse::output::{RunLength, RunOptions, run_headless};
use perfuse::scenario::Scenario;
use perfuse::sim::BackendKind;
use std::path::PathBuf;

#[derive(Parser)]
#[command(name = "perfuse", version, about = "Biphasic SPH surgical simulator: a blood-perfused liver")]
struct Cli {
    #[command(subcommand)]
    command: Option<Cmd>,
    /// Viewer (no subcommand): the scenario to open.
    #[arg(long, default_value = DEFAULT_SCENARIO)]
    scenario: PathBuf,
    /// Viewer: where the simulation runs (auto: the GPU when it is a hardware one, else the CPU).
    #[arg(long, value_enum, default_value = "auto")]
    backend: Backend,
    #[command(flatten)]
    window: WindowArgs,
    /// Viewer: record the session to this file (replay with `perfuse replay FILE --verify`).
    #[arg(long)]
    record: Option<PathBuf>,
    /// Viewer: cap the live run at this many simulated seconds per wall second (1: real time,
    /// 0.01: slow motion); default as fast as the back-end goes. Also in the Run panel.
    #[arg(long)]
    pace: Option<f64>,
}

/// The viewer's window options (the viewer on a scenario, and `perfuse replay`).
#[derive(clap::Args, Clone, Debug)]
struct WindowArgs {
    /// Viewer: quit after this many frames.
    #[arg(long)]
    frames: Option<u64>,
    /// Viewer: save the last frame (window contents) to this PNG.
    #[arg(long)]
    screenshot: Option<PathBuf>,
    /// Viewer: window size, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x800")]
    size: String,
    /// Viewer: start paused.
    #[arg(long)]
    paused: bool,
    /// Viewer: relax the organ live even when this build has kept the scenario's relaxed state from an
    /// earlier launch (in $PERFUSE_CACHE_DIR, else $XDG_CACHE_HOME/perfuse/relaxed or
    /// ~/.cache/perfuse/relaxed; PERFUSE_CACHE_DIR= keeps none); the new state replaces the kept one.
    #[arg(long)]
    fresh_relaxation: bool,
}

/// The scenario `cargo run --release` opens.
const DEFAULT_SCENARIO: &str = "assets/scenarios/liver.ron";

#[derive(Clone, Copy, ValueEnum, Debug)]
enum Backend {
    /// The GPU when a hardware adapter exists (or PERFUSE_ADAPTER names one), else the CPU.
    Auto,
    Cpu,
    Gpu,
}

/// `perfuse dmd --amplitudes`: how the mode amplitudes a_j are fitted.
#[derive(Clone, Copy, ValueEnum, Debug)]
enum Amplitudes {
    /// a = argmin ‖Φa − x_1‖ (the thesis's initial value problem, §5.2).
    Initial,
    /// Least squares over every snapshot of the record with the stabilised eigenvalues (optimal
    /// amplitudes, Jovanović, Schmid & Nichols 2014; not in the thesis).
    All,
}

impl From<Amplitudes> for perfuse::analysis::dmd::AmplitudeFit {
    fn from(a: Amplitudes) -> Self {
        match a {
            Amplitudes::Initial => Self::InitialCondition,
            Amplitudes::All => Self::AllSnapshots,
        }
    }
}

impl From<Backend> for BackendKind {
    fn from(b: Backend) -> BackendKind {
        match b {
            Backend::Auto => {
                let kind = if perfuse::sim::gpu::device::hardware_adapter_available() {
                    BackendKind::Gpu
                } else {
                    BackendKind::Cpu
                };
                log::info!("--backend auto chose {kind:?}");
                kind
            }
            Backend::Cpu => BackendKind::Cpu,
            Backend::Gpu => BackendKind::Gpu,
        }
    }
}

#[derive(Subcommand)]
enum Cmd {
    /// Run a scenario headless: CSV frames, probes.csv and summary.json.
    Run {
        /// Scenario file (RON).
        scenario: PathBuf,
        #[arg(long, value_enum, default_value = "auto")]
        backend: Backend,
        /// Simulated time to stop at \[s\] (default: the scenario's duration).
        #[arg(long, conflicts_with = "steps")]
        until: Option<f64>,
        /// Number of steps to run.
        #[arg(long)]
        steps: Option<u64>,
        /// Output directory (default: out/<scenario name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Override a scenario field, e.g. --set numerics.dx_liquid=0.0005 (repeatable).
        #[arg(long = "set", value_name = "FIELD=VALUE")]
        set: Vec<String>,
        /// Also write ParaView frames: frame_NNNNN.vtu beside each CSV frame and frames.pvd.
        #[arg(long)]
        vtk: bool,
        /// Relax the scenario even when this build has kept its relaxed state (the viewer's cache,
        /// shared; the new state replaces the kept one; PERFUSE_CACHE_DIR= keeps none).
        #[arg(long)]
        fresh_relaxation: bool,
    },
    /// Particle-steps per second of each back-end on a perfused block at several sizes (or on a scenario).
    Bench {
        /// Particle counts (liquid + solid) of the perfused block.
        #[arg(long, value_delimiter = ',', default_value = "16000,64000,256000,1000000")]
        sizes: Vec<usize>,
        /// Measure this scenario instead (adds its real-time factor and dt-limiting criterion).
        #[arg(long)]
        scenario: Option<PathBuf>,
        /// Override scenario fields, as for `run` (of --scenario, or of the perfused block: e.g.
        /// `numerics.reorder_liquid=false`).
        #[arg(long = "set", value_name = "FIELD=VALUE")]
        set: Vec<String>,
        /// Back-ends to measure (side by side; a missing GPU is reported and skipped).
        #[arg(long, value_enum, value_delimiter = ',', default_value = "cpu,gpu")]
        backends: Vec<Backend>,
        /// Minimum wall time per configuration \[s\].
        #[arg(long, default_value_t = 5.0)]
        seconds: f64,
        /// Write the rows as JSON.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Also measure each configuration while recording it as the viewer does (keyframes, state
        /// hashes) to a temporary file: overhead, keyframe cost and size, bytes per simulated second.
        #[arg(long)]
        record: bool,
        /// Generate the liquid in a random storage order: the locality a long mixing flow leaves
        /// behind, which `numerics.reorder_liquid` (default on) restores by renumbering it by cell.
        #[arg(long)]
        shuffle_liquid: bool,
        /// GPU: report the time per entry point (WGSL function, e.g. forces_solid_xsph) instead of per
        /// pass family (forces).
        #[arg(long)]
        entry_points: bool,
    },
    /// Render a scenario headless at simulated time T to a PNG (offscreen, the viewer's renderer), or a
    /// PNG sequence from T to --until every --every seconds.
    Render {
        /// Scenario file (RON).
        scenario: PathBuf,
        /// Simulated time to render \[s\] (after the scenario's relaxation); the first frame of a sequence.
        #[arg(long, default_value_t = 0.0)]
        at: f64,
        /// The PNG; a sequence goes to OUT_00000.png, OUT_00001.png, … (OUT without its extension).
        #[arg(long, default_value = "frame.png")]
        out: PathBuf,
        /// Render a sequence: a frame every DT seconds of simulated time from --at to --until.
        #[arg(long, value_name = "DT", requires = "until")]
        every: Option<f64>,
        /// Last time of a sequence \[s\] (frames at T, T+DT, … up to it).
        #[arg(long, value_name = "T2", requires = "every")]
        until: Option<f64>,
        /// Image size, WIDTHxHEIGHT.
        #[arg(long, default_value = "1280x720")]
        size: String,
        #[arg(long, value_enum, default_value = "auto")]
        backend: Backend,
        /// Colour the tissue by: tissue, stress, liquid, broken.
        #[arg(long, default_value = "tissue")]
        field: String,
        /// Draw blood as spheres instead of the screen-space fluid surface.
        #[arg(long)]
        no_fluid: bool,
        #[arg(long = "set", value_name = "FIELD=VALUE")]
        set: Vec<String>,
        /// After the (last) image, draw the same state N more times and print the GPU milliseconds of each
        /// render pass (timestamp queries: scene, the screen-space blood passes, composite) and the frame
        /// time — the renderer's cost at --size.
        #[arg(long, value_name = "N")]
        timing: Option<u32>,
        /// Relax the scenario even when this build has kept its relaxed state (as the viewer does; the
        /// new state replaces the kept one).
        #[arg(long)]
        fresh_relaxation: bool,
    },
    /// Dynamic mode decomposition of the frames of a `perfuse run` (thesis ch. 5): plots and dmd.json.
    Dmd {
        /// Folder with frame_NNNNN.csv (and summary.json, which gives the frame interval).
        frames: PathBuf,
        /// Truncation rank r.
        #[arg(long, conflicts_with = "energy")]
        rank: Option<usize>,
        /// Keep the modes holding this fraction of the singular-value energy (e.g. 0.99).
        #[arg(long)]
        energy: Option<f64>,
        /// Include velocities in the state vector (Table 5.1 case 2).
        #[arg(long)]
        velocities: bool,
        /// Time between frames \[s\] (default: summary.json's frame_interval_s).
        #[arg(long)]
        frame_interval: Option<f64>,
        /// Amplitude fit: `initial` (from the first snapshot, thesis §5.2) or `all` (least squares over
        /// the whole record, stabilised; spreads the error of a nonlinear record over the window).
        #[arg(long, value_enum, default_value = "initial")]
        amplitudes: Amplitudes,
        #[arg(long, default_value = "out/dmd")]
        out: PathBuf,
    },
    /// Replay a recorded session in the viewer (timeline, seek, take over), or headless with
    /// --headless / --verify (--verify compares the state hashes stored in it).
    Replay {
        /// Recording (.pfrec) written by the viewer (--record, the record button) or a scripted session.
        file: PathBuf,
        /// Re-simulate headless and compare every stored state hash (bit-identical on the same adapter).
        #[arg(long)]
        verify: bool,
        /// Replay headless without the viewer (prints the final state hash).
        #[arg(long)]
        headless: bool,
        /// Headless: stop at this simulated time \[s\], going there through the nearest keyframe.
        #[arg(long)]
        seek: Option<f64>,
        /// Back-end (default: the one that recorded it; bit-identical only there).
        #[arg(long, value_enum)]
        backend: Option<Backend>,
        #[command(flatten)]
        window: WindowArgs,
        /// Export the replay to ParaView: DIR/frame_NNNNN.vtu and DIR/frames.pvd.
        #[arg(long, value_name = "DIR")]
        vtk: Option<PathBuf>,
        /// With --vtk: a frame every SECONDS of simulated time, plus the final state (default: the
        /// scenario's output.frame_interval, else 0.01).
        #[arg(long, value_name = "SECONDS", requires = "vtk")]
        every: Option<f64>,
    },
    /// Scripted hemorrhage through the closed-loop cardiovascular model: vitals.csv and PNG plots.
    Vitals {
        /// Fraction of the blood volume removed (0..0.6).
        #[arg(long, default_value_t = 0.35)]
        loss: f64,
        /// Bleeding starts at this time \[s\] (after a settled baseline).
        #[arg(long, default_value_t = 10.0)]
        start: f64,
        /// Bleeding lasts this long \[s\] (constant rate).
        #[arg(long, default_value_t = 600.0)]
        over: f64,
        /// Total simulated time \[s\].
        #[arg(long, default_value_t = 660.0)]
        duration: f64,
        #[arg(long, default_value = "out/vitals")]
        out: PathBuf,
    },
    /// Run the validation cases against their analytic references: report.json and PNG plots.
    Validate {
        /// Run only this case (poiseuille, brinkman, convergence, hydrostatic, cantilever; wicking,
        /// liver_scalpel, projectile, syringe, dmd, capsule and liver_rest run only when named: the three fabric cases of SPEC §7.12,
        /// ≈ 45 min with --quick on a CPU; the liver cut twice, SPEC §9.3 L1/L2, ≈ 2.5 h —
        /// liver_scalpel_L1 or liver_scalpel_L2 runs one of the two; the projectile of SPEC §7.10
        /// for 1 s (--quick: relaxed, then 0.2 s at 12³, ≈ 50 min on a CPU); the syringe of SPEC §7.8 for 2 s; dmd: the oscillating wall and the broken dam with DMD, SPEC §7.13–7.14;
        /// capsule: an intact capsule's leaked blood over 10⁴ steps, hanging under gravity and indented 30 %, issue 6 §1;
        /// liver_rest: the default liver relaxed and at rest on its bed, issue 6 §4, ≈ 4 min with --quick on a CPU).
        #[arg(long)]
        case: Option<String>,
        /// Reduced resolutions (what the test suite runs).
        #[arg(long)]
        quick: bool,
        #[arg(long, default_value = "out/validate")]
        out: PathBuf,
        #[arg(long, value_enum, default_value = "auto")]
        backend: Backend,
        /// Edit the named case's scenario (liver_scalpel*, projectile, syringe, liver_rest) after its preset, as
        /// `perfuse run --set` does, e.g. `--set numerics.hourglass=0.72`; repeatable; `report.json`
        /// lists the edits under `overrides`.
        #[arg(long = "set", value_name = "FIELD=VALUE")]
        set: Vec<String>,
        /// Relax each case's scenario even when this build has kept its relaxed state (the viewer's
        /// cache, shared; the new state replaces the kept one; PERFUSE_CACHE_DIR= keeps none).
        #[arg(long)]
        fresh_relaxation: bool,
    },
}

fn main() {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    if let Err(e) = real_main() {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

/// `WIDTHxHEIGHT` → (width, height).
fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) =
        s.split_once(['x', 'X']).with_context(|| format!("--size `{s}`: write it as WIDTHxHEIGHT, e.g. 1280x720"))?;
    let w: u32 = w.trim().parse().with_context(|| format!("--size `{s}`: width is not a number"))?;
    let h: u32 = h.trim().parse().with_context(|| format!("--size `{s}`: height is not a number"))?;
    if !(16..=8192).contains(&w) || !(16..=8192).contains(&h) {
        bail!("--size `{s}`: each side must be 16..8192 pixels");
    }
    Ok((w, h))
}

fn parse_field(s: &str) -> Result<perfuse::render::FieldMode> {
    use perfuse::render::FieldMode;
    Ok(match s {
        "tissue" | "plain" => FieldMode::Plain,
        "stress" => FieldMode::Stress,
        "liquid" => FieldMode::LiquidFraction,
        "broken" => FieldMode::BrokenBonds,
        other => bail!("--field `{other}`: choose tissue, stress, liquid or broken"),
    })
}

/// `OUT_00007.png` for frame 7 of a sequence written to `OUT.png`.
fn sequence_path(out: &std::path::Path, k: usize) -> PathBuf {
    let stem = out.file_stem().map_or_else(|| "frame".into(), |s| s.to_string_lossy().into_owned());
    let ext = out.extension().map_or_else(|| "png".into(), |e| e.to_string_lossy().into_owned());
    out.with_file_name(format!("{stem}_{k:05}.{ext}"))
}

/// Most frames one `render --every` writes (a typo such as --every 1e-9 should not fill a disk).
const MAX_RENDER_FRAMES: f64 = 100_000.0;

#[allow(clippy::too_many_arguments)]
fn render_command(
    scenario: &std::path::Path,
    at: f64,
    sequence: Option<(f64, f64)>,
    out: &std::path::Path,
    size: &str,
    backend: Backend,
    field: &str,
    no_fluid: bool,
    set: &[String],
    timing: Option<u32>,
    fresh_relaxation: bool,
) -> Result<()> {
    use perfuse::render::{Renderer, snapshot};
    use perfuse::sim::Simulation;
    use perfuse::sim::gpu::GpuContext;
    let size = parse_size(size)?;
    let field = parse_field(field)?;
    if !(at.is_finite() && at >= 0.0) {
        bail!("--at must be a time ≥ 0 s, got {at}");
    }
    // Frame times T + k·DT (multiplied, not summed, so they do not drift) up to --until.
    let times: Vec<f64> = match sequence {
        None => vec![at],
        Some((every, until)) => {
            if !(every.is_finite() && every > 0.0) {
                bail!("--every must be a positive, finite number of seconds, got {every}");
            }
            if !(until.is_finite() && until >= at) {
                bail!("--until must be a time ≥ --at ({at} s), got {until}");
            }
            let n = ((until - at) / every + 1e-9).floor() + 1.0;
            if n > MAX_RENDER_FRAMES {
                bail!("--every {every} from {at} to {until} s makes {n} frames; at most {MAX_RENDER_FRAMES} per run");
            }
            (0..n as usize).map(|k| at + k as f64 * every).collect()
        }
    };
    let sc = Scenario::load_with_overrides(scenario, set)?;
    print_warnings(&sc);
    let ctx = GpuContext::new().context("rendering needs a GPU adapter (or the lavapipe software adapter)")?;
    let kind: BackendKind = backend.into();
    let mut sim = Simulation::with_gpu(&sc, (kind == BackendKind::Gpu).then(|| ctx.clone()))?;
    let bar = perfuse::output::progress_bar();
    // the relaxed state the viewer or an earlier render kept, if this build has one (bit for bit the same)
    let cache = perfuse::replay::relaxed_cache::RelaxedCache::user_default();
    let kept =
        perfuse::replay::relaxed_cache::relax_with_cache(cache.as_ref(), fresh_relaxation, &sc, &mut sim, |_| {
            bar.tick()
        })?;
    if let Some(f) = kept {
        bar.suspend(|| eprintln!("relaxed state from {} (--fresh-relaxation relaxes again)", f.display()));
    }
    let mut renderer = Renderer::new(&ctx.device, &ctx.queue)?;
    renderer.settings.field = field;
    renderer.settings.field_scale = field.default_scale();
    renderer.settings.fluid = !no_fluid;
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    // One camera for the whole sequence (fitted after the relaxation), so the frames line up.
    let mut camera = None;
    for (k, &t) in times.iter().enumerate() {
        sim.advance_until(t, u64::MAX, |t| bar.set_message(format!("t = {t:.4} s")))?;
        let camera = camera.get_or_insert_with(|| snapshot::default_camera(&sim));
        let img = snapshot::render_image(&sim, &ctx, &mut renderer, camera, size)?;
        let path = if sequence.is_some() { sequence_path(out, k) } else { out.to_path_buf() };
        img.save(&path).with_context(|| format!("writing {}", path.display()))?;
        bar.suspend(|| {
            println!("{}: t = {:.4} s rendered to {} ({}×{})", sc.name, sim.time(), path.display(), size.0, size.1)
        });
    }
    if let (Some(n), Some(camera)) = (timing.filter(|n| *n > 0), camera.as_ref()) {
        let snapshot::FrameTiming { passes, wall_ms } =
            snapshot::time_frames(&sim, &ctx, &mut renderer, camera, size, n)?;
        bar.finish_and_clear();
        println!("render timing at {}×{} over {n} frames ({}):", size.0, size.1, ctx.info.name);
        if passes.is_empty() {
            println!("  no timestamp queries on this adapter: wall time only");
        }
        for (name, ms) in &passes {
            println!("  {name:<16} {ms:>8.3} ms");
        }
        let blood: f64 =
            passes.iter().filter(|(n, _)| n.starts_with("blood") || n.starts_with("filter")).map(|p| p.1).sum();
        let gpu: f64 = passes.iter().map(|p| p.1).sum();
        if !passes.is_empty() {
            println!("  GPU total {gpu:.3} ms, of which screen-space blood (thickness, depth, filters) {blood:.3} ms");
        }
        println!("  frame (submit to GPU done) {wall_ms:.3} ms");
    }
    bar.finish_and_clear();
    Ok(())
}

/// `perfuse replay FILE --vtk DIR [--every S]`: the replay with a `.vtu` every S simulated seconds
/// and the final state, listed in `DIR/frames.pvd`.
fn replay_to_vtk(
    rec: &perfuse::replay::format::Recording,
    backend: BackendKind,
    verify: bool,
    dir: &std::path::Path,
    every: Option<f64>,
) -> Result<perfuse::replay::session::ReplayOutcome> {
    use perfuse::output::vtk::VtkSeries;
    use perfuse::replay::session;
    let every = match every {
        Some(dt) => dt,
        None => session::recorded_scenario(rec)?.output.frame_interval.unwrap_or(0.01),
    };
    let mut series = VtkSeries::create(dir)?;
    let out = session::replay_with(rec, backend, verify, Some(every), |state, params| {
        series.write(&format!("frame_{:05}.vtu", series.frames()), state, params)?;
        Ok::<(), anyhow::Error>(())
    })?;
    let bytes = series.bytes;
    let frames = series.finish()?;
    println!(
        "wrote {frames} VTK frames ({:.1} MB, every {every} s and the final state) and {} to {}",
        bytes as f64 / 1e6,
        perfuse::output::vtk::PVD_NAME,
        dir.display()
    );
    Ok(out)
}

/// The session's metrics at the end of a viewer session with a patient.
fn print_session(m: Option<&perfuse::analysis::session::SessionReport>) {
    let Some(m) = m else { return };
    let secs = |t: Option<f64>| t.map_or("none".to_string(), |t| format!("{t:.2} s"));
    println!(
        "session: {:.1} mL blood lost, peak loss rate {:.1} mL/min, {} bonds broken, first cut {}, hemostasis {} \
         (cut to hemostasis {})",
        m.blood_lost_ml,
        m.peak_loss_rate_ml_min,
        m.broken_bonds,
        secs(m.first_cut_s),
        secs(m.hemostasis_s),
        secs(m.cut_to_hemostasis_s)
    );
}

/// The scenario's non-fatal notes (`scenario::warnings`: a box edge a hair short of a layer), on
/// stderr before the work starts.
fn print_warnings(sc: &Scenario) {
    for w in perfuse::scenario::warnings(sc) {
        eprintln!("warning: scenario `{}`, {w}", sc.name);
    }
}

/// The viewer on `cli.scenario`.
fn viewer(cli: &Cli) -> Result<()> {
    let path = if cli.scenario.is_relative() && !cli.scenario.exists() {
        // `cargo run` from elsewhere: the shipped scenarios live beside the manifest.
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(&cli.scenario)
    } else {
        cli.scenario.clone()
    };
    let scenario = Scenario::load(&path)?;
    print_warnings(&scenario);
    let gpu_simulation = match cli.backend {
        Backend::Auto => None,
        Backend::Cpu => Some(false),
        Backend::Gpu => Some(true),
    };
    if let Some(p) = cli.pace {
        let (lo, hi) = perfuse::app::sim_thread::PACE_RANGE;
        if !(p.is_finite() && (lo..=hi).contains(&p)) {
            bail!("--pace {p}: give simulated seconds per wall second between {lo} and {hi} (1 = real time)");
        }
    }
    open_viewer(scenario, path, gpu_simulation, &cli.window, cli.record.clone(), None, cli.pace)
}

/// Opens the viewer (live on `scenario`, or replaying `replay`) with the window options, then prints
/// what it reports.
fn open_viewer(
    scenario: Scenario,
    scenario_path: PathBuf,
    gpu_simulation: Option<bool>,
    window: &WindowArgs,
    record: Option<PathBuf>,
    replay: Option<perfuse::replay::format::Recording>,
    pace: Option<f64>,
) -> Result<()> {
    if window.frames == Some(0) {
        bail!("--frames must be at least 1");
    }
    let opts = perfuse::app::ViewerOptions {
        scenario,
        scenario_path,
        gpu_simulation,
        frames: window.frames,
        screenshot: window.screenshot.clone(),
        size: parse_size(&window.size)?,
        paused: window.paused,
        record,
        replay,
        pace,
        relaxed_cache: perfuse::replay::relaxed_cache::RelaxedCache::user_default(),
        fresh_relaxation: window.fresh_relaxation,
    };
    let report = perfuse::app::run(opts)?;
    println!(
        "viewer: {} frames, {:.1} fps; simulation {} steps, {:.1} steps/s",
        report.frames, report.fps, report.sim_steps, report.steps_per_s
    );
    print_session(report.session.as_ref());
    if let Some(p) = &report.screenshot {
        if !p.exists() {
            bail!("the screenshot {} was not written", p.display());
        }
        println!("screenshot: {}", p.display());
    }
    Ok(())
}

fn real_main() -> Result<()> {
    let cli = Cli::parse();
    let Some(command) = cli.command else { return viewer(&cli) };
    match command {
        Cmd::Dmd { frames, rank, energy, velocities, frame_interval, amplitudes, out } => {
            use perfuse::analysis::dmd;
            let dt = match frame_interval {
                Some(dt) => dt,
                None => {
                    let path = frames.join("summary.json");
                    let text = std::fs::read_to_string(&path).with_context(|| {
                        format!("{}: give --frame-interval or the run's summary.json", path.display())
                    })?;
                    let v: serde_json::Value =
                        serde_json::from_str(&text).with_context(|| format!("{} is not JSON", path.display()))?;
                    v.get("frame_interval_s").and_then(|x| x.as_f64()).with_context(|| {
                        format!("{} has no frame_interval_s (run with output.frame_interval set)", path.display())
                    })?
                }
            };
            if !(dt.is_finite() && dt > 0.0) {
                bail!("frame interval {dt} s must be positive and finite");
            }
            let sel = dmd::rank_selection_from_cli(rank, energy)?;
            let report = dmd::run_dmd(&frames, dt, dmd::FrameFields { velocities }, sel, amplitudes.into(), &out)?;
            println!(
                "DMD of {}: rank {}, dominant frequency {}, reconstruction error {:.3e}; wrote dmd.json and plots to {}",
                frames.display(),
                report.rank,
                report.dominant_frequency_hz.map_or("none".to_string(), |f| format!("{f:.4} Hz")),
                report.reconstruction_error,
                out.display()
            );
            Ok(())
        }
        Cmd::Replay { file, verify, headless, seek, backend, window, vtk, every } => {
            use perfuse::replay::{format::read_recording_file, session};
            // Checked before the (possibly long) read and replay.
            if let Some(dt) = every
                && !(dt.is_finite() && dt > 0.0)
            {
                bail!("--every must be a positive, finite number of seconds, got {dt}");
            }
            let rec = read_recording_file(&file)?;
            for w in &rec.warnings {
                eprintln!("warning: {w}");
            }
            let backend = match backend {
                Some(b) => BackendKind::from(b),
                None if rec.header.backend.to_ascii_lowercase().starts_with("gpu") => BackendKind::Gpu,
                None => BackendKind::Cpu,
            };
            println!(
                "{}: scenario `{}`, recorded by {} on {} {}, {} chunks ({} keyframes){}{}",
                file.display(),
                rec.header.scenario_name,
                rec.header.program_version,
                rec.header.backend,
                rec.header.adapter,
                rec.chunks.len(),
                rec.chunks_of(perfuse::replay::format::ChunkKind::Keyframe).count(),
                rec.header
                    .parent
                    .as_ref()
                    .map(|p| format!(", a branch of {} at t = {:.6} s (step {})", p.file, p.t_s, p.step))
                    .unwrap_or_default(),
                if rec.complete { "" } else { " (incomplete: replaying up to the last good chunk)" }
            );
            if let Some(t) = seek
                && !t.is_finite()
            {
                bail!("--seek {t}: give a finite time in seconds");
            }
            if !(verify || headless || seek.is_some() || vtk.is_some()) {
                let scenario = session::recorded_scenario(&rec)?;
                let gpu = Some(backend == BackendKind::Gpu);
                return open_viewer(scenario, file.clone(), gpu, &window, None, Some(rec), None);
            }
            let out = if let Some(dir) = &vtk {
                if seek.is_some() {
                    bail!("--seek and --vtk: export the whole recording (leave out --seek)");
                }
                replay_to_vtk(&rec, backend, verify, dir, every)?
            } else {
                let mut player = session::Player::new(rec, backend, verify)?;
                match seek {
                    Some(t) => player.seek_time(t)?,
                    None => player.play_to_end()?,
                }
                player.finish()?
            };
            println!(
                "replayed {} commands to step {} (t = {:.6} s, {} keyframes restored); final state hash {:016x}",
                out.commands, out.steps, out.t, out.keyframes_restored, out.final_hash
            );
            for w in out.warnings.iter().filter(|w| w.starts_with("keyframe")) {
                eprintln!("warning: {w}");
            }
            if verify {
                println!("{} state hashes checked, {} mismatches", out.hashes_checked, out.mismatches.len());
                if let Some((step, want, got)) = out.mismatches.first() {
                    bail!(
                        "replay diverged from the recording at step {step} (hash {want:016x} recorded, {got:016x} replayed); \
                         replay on the back-end and adapter that recorded it"
                    );
                }
            }
            Ok(())
        }
        Cmd::Vitals { loss, start, over, duration, out } => {
            use perfuse::analysis::hemorrhage;
            if !(0.0..=0.6).contains(&loss) {
                bail!("--loss {loss}: give a fraction of the blood volume in 0..0.6 (0.35 = ATLS class III)");
            }
            for (name, v) in [("--start", start), ("--over", over), ("--duration", duration)] {
                if !(v.is_finite() && (0.0..=86_400.0).contains(&v)) {
                    bail!("{name} {v}: give seconds in 0..86400");
                }
            }
            if loss > 0.0 && over <= 0.0 {
                bail!("--over {over}: the loss is removed at a constant rate over this time; give it in seconds > 0");
            }
            if duration <= 0.0 {
                bail!("--duration {duration}: give the simulated time in seconds > 0");
            }
            let samples = hemorrhage::scripted_hemorrhage(Default::default(), loss, start, over, duration, 0.5)?;
            hemorrhage::write_outputs(&samples, &out).map_err(anyhow::Error::msg)?;
            let windows = hemorrhage::pulse_windows(Default::default(), loss, start, over, duration)?;
            hemorrhage::write_pulse_plot(&windows, &out).map_err(anyhow::Error::msg)?;
            if let Some(last) = samples.last() {
                let v = &last.vitals;
                println!(
                    "t = {:.0} s: {:.0}% lost ({:.0} mL), MAP {:.0} mmHg, {:.0}/{:.0} mmHg, HR {:.0} bpm, CO {:.2} L/min, class {}",
                    last.t_s,
                    100.0 * v.blood_lost_fraction,
                    v.blood_lost_ml,
                    v.map_mmhg,
                    v.systolic_mmhg,
                    v.diastolic_mmhg,
                    v.hr_bpm,
                    v.cardiac_output_l_min,
                    v.shock_class
                );
            }
            println!("wrote vitals.csv, vitals.png, hepatic_inflow.png, hepatic_pulse.png to {}", out.display());
            Ok(())
        }
        Cmd::Render {
            scenario,
            at,
            out,
            every,
            until,
            size,
            backend,
            field,
            no_fluid,
            set,
            timing,
            fresh_relaxation,
        } => {
            let sequence = every.zip(until);
            render_command(
                &scenario,
                at,
                sequence,
                &out,
                &size,
                backend,
                &field,
                no_fluid,
                &set,
                timing,
                fresh_relaxation,
            )
        }
        Cmd::Run { scenario, backend, until, steps, out, set, vtk, fresh_relaxation } => {
            let sc = Scenario::load_with_overrides(&scenario, &set)?;
            print_warnings(&sc);
            if let Some(t) = until
                && !(t.is_finite() && t > 0.0)
            {
                bail!("--until must be a positive, finite number of seconds, got {t}");
            }
            let length = match (until, steps) {
                (Some(t), _) => Some(RunLength::Until(t)),
                (None, Some(n)) => Some(RunLength::Steps(n)),
                _ => None,
            };
            let out = out.unwrap_or_else(|| PathBuf::from("out").join(&sc.name));
            let opts = RunOptions {
                backend: backend.into(),
                length,
                out: Some(out.clone()),
                progress: true,
                vtk,
                // the relaxed state the viewer, `render`, `validate` or an earlier run kept (bit for bit the same)
                relaxed_cache: perfuse::replay::relaxed_cache::RelaxedCache::user_default(),
                fresh_relaxation,
            };
            let summary = run_headless(&sc, &opts).with_context(|| format!("running {}", scenario.display()))?;
            println!(
                "{}: {} steps, t = {:.4} s, {:.3e} particle-steps/s, dt {:.2e}..{:.2e} s, mass conserved: {}",
                sc.name,
                summary.steps,
                summary.simulated_time_s,
                summary.particle_steps_per_s,
                summary.dt_min_s,
                summary.dt_max_s,
                summary.mass.conserved
            );
            println!("wrote {} frames and summary.json to {}", summary.frames_written, out.display());
            if vtk {
                println!("ParaView: open {}", out.join(perfuse::output::vtk::PVD_NAME).display());
            }
            if let Some(d) = &summary.divergence {
                bail!("{d}");
            }
            Ok(())
        }
        Cmd::Bench { sizes, scenario, set, backends, seconds, json, record, shuffle_liquid, entry_points } => {
            let setup = perfuse::bench::Setup { shuffled_liquid: shuffle_liquid, entry_points };
            if !(seconds.is_finite() && seconds > 0.0) {
                bail!("--seconds must be a positive, finite number of seconds, got {seconds}");
            }
            let scenarios: Vec<perfuse::scenario::Scenario> = match &scenario {
                Some(path) => {
                    let sc = Scenario::load_with_overrides(path, &set)?;
                    print_warnings(&sc);
                    vec![sc]
                }
                None => {
                    if sizes.is_empty() || sizes.iter().any(|n| !(16..=20_000_000).contains(n)) {
                        bail!("--sizes must list particle counts between 16 and 20000000");
                    }
                    let block = |n: usize| -> Result<Scenario, perfuse::scenario::ScenarioError> {
                        let mut sc = perfuse::bench::perfused_block(n)?;
                        for spec in &set {
                            sc = sc.with_override(spec)?;
                        }
                        sc.validate("(bench block)")?;
                        Ok(sc)
                    };
                    sizes.iter().map(|&n| block(n)).collect::<Result<_, _>>()?
                }
            };
            let mut rows = Vec::new();
            for sc in &scenarios {
                for &b in &backends {
                    eprintln!(
                        "measuring {} on {:?}{}…",
                        sc.name,
                        b,
                        if record { ", without and with recording" } else { "" }
                    );
                    let measured = if record {
                        let file = std::env::temp_dir().join(format!("perfuse-bench-{}.pfrec", std::process::id()));
                        perfuse::bench::record_overhead(sc, b.into(), seconds, &file, setup).map(|(plain, rec)| {
                            eprint!("{}", perfuse::bench::table(std::slice::from_ref(&plain)));
                            rec
                        })
                    } else {
                        perfuse::bench::measure_with(sc, b.into(), seconds, 3, u64::MAX, None, setup)
                    };
                    let row = match measured {
                        Ok(row) => row,
                        Err(perfuse::bench::BenchError::Sim(perfuse::sim::SimError::Gpu(msg)))
                            if backends.len() > 1 =>
                        {
                            eprintln!("skipping the GPU back-end: {msg}");
                            continue;
                        }
                        Err(e) => return Err(anyhow::Error::new(e).context(format!("benchmarking {}", sc.name))),
                    };
                    eprint!("{}", perfuse::bench::table(std::slice::from_ref(&row)));
                    rows.push(row);
                }
            }
            println!("{}", perfuse::bench::table(&rows));
            if record {
                println!("{}", perfuse::bench::record_table(&rows));
            }
            for &b in &backends {
                let name = format!("{:?}", BackendKind::from(b)).to_lowercase();
                let of: Vec<&perfuse::bench::BenchRow> = rows.iter().filter(|r| r.backend == name).collect();
                if let Some(slope) = perfuse::bench::cost_slope(&of) {
                    println!("{name}: fitted slope of time per step vs N = {slope:.3}");
                }
            }
            if let Some(path) = json {
                std::fs::write(&path, serde_json::to_string_pretty(&rows)?)
                    .with_context(|| format!("writing {}", path.display()))?;
                println!("wrote {}", path.display());
            }
            Ok(())
        }
        Cmd::Validate { case, quick, out, backend, set, fresh_relaxation } => {
            // the relaxed states the viewer, `render` or an earlier validation kept (bit for bit the same)
            let cache = perfuse::replay::relaxed_cache::RelaxedCache::user_default();
            let relax = perfuse::analysis::relaxation::RelaxWith { cache: cache.as_ref(), fresh: fresh_relaxation };
            let report = perfuse::analysis::validate::run_validation(
                case.as_deref(),
                quick,
                &out,
                backend.into(),
                true,
                &set,
                relax,
            )?;
            for c in &report.cases {
                println!(
                    "{:<28} {:<22} {:>10.4} (tol {:>7.4})  {}  {:.1} s",
                    c.name,
                    c.metric,
                    c.value,
                    c.tolerance,
                    if c.pass { "PASS" } else { "FAIL" },
                    c.wall_time_s
                );
            }
            println!("report: {}", out.join("report.json").display());
            if report.cases.iter().any(|c| !c.pass) {
                bail!("some validation cases failed");
            }
            Ok(())
        }
    }
}
