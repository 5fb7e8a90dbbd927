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
    command: Cmd,
}

#[derive(Clone, Copy, ValueEnum, Debug)]
enum Backend {
    /// The GPU when a hardware adapter exists (or PERFUSE_ADAPTER names one), else the CPU.
    Auto,
    Cpu,
    Gpu,
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
        /// Simulated time to stop at [s] (default: the scenario's duration).
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
    },
    /// Particle-steps per second of each back-end on a perfused block at several sizes (or on a scenario).
    Bench {
        /// Particle counts (liquid + solid) of the perfused block.
        #[arg(long, value_delimiter = ',', default_value = "16000,64000,256000,1000000")]
        sizes: Vec<usize>,
        /// Measure this scenario instead (adds its real-time factor and dt-limiting criterion).
        #[arg(long)]
        scenario: Option<PathBuf>,
        /// Override scenario fields (with --scenario), as for `run`.
        #[arg(long = "set", value_name = "FIELD=VALUE")]
        set: Vec<String>,
        /// Back-ends to measure (side by side; a missing GPU is reported and skipped).
        #[arg(long, value_enum, value_delimiter = ',', default_value = "cpu,gpu")]
        backends: Vec<Backend>,
        /// Minimum wall time per configuration [s].
        #[arg(long, default_value_t = 5.0)]
        seconds: f64,
        /// Write the rows as JSON.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Run the validation cases against their analytic references: report.json and PNG plots.
    Validate {
        /// Run only this case (poiseuille, brinkman, convergence, hydrostatic, cantilever).
        #[arg(long)]
        case: Option<String>,
        /// Reduced resolutions (what the test suite runs).
        #[arg(long)]
        quick: bool,
        #[arg(long, default_value = "out/validate")]
        out: PathBuf,
        #[arg(long, value_enum, default_value = "auto")]
        backend: Backend,
    },
}

fn main() {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    if let Err(e) = real_main() {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

fn real_main() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Cmd::Run { scenario, backend, until, steps, out, set } => {
            let sc = Scenario::load_with_overrides(&scenario, &set)?;
            if let Some(t) = until
                && !(t.is_finite() && t > 0.0)
            {
                bail!("--until must be a positive number of seconds, got {t}");
            }
            let length = match (until, steps) {
                (Some(t), _) => Some(RunLength::Until(t)),
                (None, Some(n)) => Some(RunLength::Steps(n)),
                _ => None,
            };
            let out = out.unwrap_or_else(|| PathBuf::from("out").join(&sc.name));
            let opts = RunOptions { backend: backend.into(), length, out: Some(out.clone()), progress: true };
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
            if let Some(d) = &summary.divergence {
                bail!("{d}");
            }
            Ok(())
        }
        Cmd::Bench { sizes, scenario, set, backends, seconds, json } => {
            if !(seconds.is_finite() && seconds > 0.0) {
                bail!("--seconds must be positive, got {seconds}");
            }
            let scenarios: Vec<perfuse::scenario::Scenario> = match &scenario {
                Some(path) => vec![Scenario::load_with_overrides(path, &set)?],
                None => {
                    if sizes.is_empty() || sizes.iter().any(|n| !(16..=20_000_000).contains(n)) {
                        bail!("--sizes must list particle counts between 16 and 20000000");
                    }
                    sizes.iter().map(|&n| perfuse::bench::perfused_block(n)).collect::<Result<_, _>>()?
                }
            };
            let mut rows = Vec::new();
            for sc in &scenarios {
                for &b in &backends {
                    eprintln!("measuring {} on {:?}…", sc.name, b);
                    let row = match perfuse::bench::measure(sc, b.into(), seconds, 3, u64::MAX) {
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
        Cmd::Validate { case, quick, out, backend } => {
            let report =
                perfuse::analysis::validate::run_validation(case.as_deref(), quick, &out, backend.into(), true)?;
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
