//! The relaxed state of a scenario, kept on disk between viewer launches.
//!
//! A scenario's damped relaxation (SPEC §7.5) settles the organ under its weight before t = 0. On the
//! default liver it is 0.1 s of simulated time — minutes on a laptop's integrated GPU or on the CPU —
//! and a trainee would wait for it on every launch. The first launch keeps the state at t = 0 here;
//! later launches of the same scenario, with the same build, back-end and adapter, start from it.
//!
//! Exactness: a relaxation is deterministic on one back-end and adapter (the state-hash tests of the
//! replay), so a cached state is bit for bit the state the relaxation would reach again. The key is
//! therefore everything that decides that state: the scenario's self-contained text
//! ([`scenario_text`], `--set` overrides applied) and the bytes of its meshes, the back-end and adapter
//! names, the program version
//! and the running executable's own bytes (a rebuilt program never reads another build's state, whose
//! physics may differ under the same version number). The file is a one-keyframe recording
//! (`format`), so the container's checksums, its version and its header's scenario hash guard it, and
//! `perfuse replay FILE --headless` can inspect one. A file that does not read back is reported and
//! the relaxation runs live again; nothing is lost.
//!
//! Where: `$PERFUSE_CACHE_DIR` (empty: no cache), else `$XDG_CACHE_HOME/perfuse/relaxed`, else
//! `$HOME/.cache/perfuse/relaxed`. The [`KEEP`] most recently written files are kept.

use super::format::{ReplayError, fnv1a64, read_recording_file};
use super::session::{Keyframe, Recorder, scenario_text};
use crate::scenario::Scenario;
use crate::sim::Simulation;
use crate::sim::physiology::Patient;
use crate::sim::snapshot::Snapshot;
use std::path::{Path, PathBuf};

/// Cached relaxed states kept per cache folder (the oldest beyond this are removed after a write).
pub const KEEP: usize = 8;

/// Why a cached state could not be used or kept.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CacheError {
    #[error(transparent)]
    Replay(#[from] ReplayError),
    #[error("cached relaxed state {file} does not fit: {detail}; the relaxation runs again and replaces it")]
    Unusable { file: String, detail: String },
    #[error("cannot keep the relaxed state in {dir}: {source}")]
    Io {
        dir: String,
        #[source]
        source: std::io::Error,
    },
}

/// A folder of cached relaxed states.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RelaxedCache {
    dir: PathBuf,
}

/// The back-end and adapter a state belongs to ([`Simulation::backend_name`],
/// [`Simulation::adapter_name`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Engine {
    pub backend: String,
    pub adapter: String,
}

impl Engine {
    pub fn of(sim: &Simulation) -> Self {
        Engine { backend: sim.backend_name(), adapter: sim.adapter_name() }
    }
}

/// A cached relaxed state, restored.
#[derive(Debug)]
pub struct Restored {
    pub file: PathBuf,
    /// The snapshot that was restored (the viewer keeps it for Reset).
    pub snapshot: Snapshot,
    pub patient: Option<Patient>,
}

impl RelaxedCache {
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        RelaxedCache { dir: dir.into() }
    }

    /// The user's cache folder (module docs), or `None` when there is none or `PERFUSE_CACHE_DIR` is
    /// set empty.
    pub fn user_default() -> Option<Self> {
        let var = |k: &str| std::env::var_os(k);
        if let Some(d) = var("PERFUSE_CACHE_DIR") {
            return (!d.is_empty()).then(|| Self::new(d));
        }
        let base = var("XDG_CACHE_HOME")
            .filter(|d| Path::new(d).is_absolute())
            .map(PathBuf::from)
            .or_else(|| var("HOME").filter(|d| !d.is_empty()).map(|h| PathBuf::from(h).join(".cache")))?;
        Some(Self::new(base.join("perfuse").join("relaxed")))
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The file that holds (or would hold) the relaxed state of `scenario` on `engine`.
    pub fn path_for(&self, scenario: &Scenario, engine: &Engine) -> PathBuf {
        let text = scenario_text(scenario);
        let key = format!(
            "{}\u{0}{}\u{0}{}\u{0}{:016x}\u{0}{:016x}\u{0}{}",
            env!("CARGO_PKG_VERSION"),
            engine.backend,
            engine.adapter,
            build_id(),
            mesh_id(scenario),
            text
        );
        let stem: String = scenario
            .name
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() || c == '_' { c } else { '-' })
            .take(40)
            .collect();
        self.dir.join(format!("{stem}-{:016x}.pfrec", fnv1a64(key.as_bytes())))
    }

    /// Restores the cached relaxed state of `scenario` into `sim` (built from it, not stepped):
    /// `Ok(None)` when none is cached; an error when a file is there but unusable (`sim` is then
    /// untouched, or as built, and the caller relaxes live).
    pub fn restore(&self, scenario: &Scenario, sim: &mut Simulation) -> Result<Option<Restored>, CacheError> {
        let engine = Engine::of(sim);
        let file = self.path_for(scenario, &engine);
        if !file.exists() {
            return Ok(None);
        }
        let name = file.display().to_string();
        let unusable = |detail: String| CacheError::Unusable { file: name.clone(), detail };
        let rec = read_recording_file(&file)?;
        rec.check_scenario(&scenario_text(scenario))?;
        if !rec.complete || !rec.warnings.is_empty() {
            return Err(unusable("the file is incomplete or damaged".into()));
        }
        if rec.header.backend != engine.backend || rec.header.adapter != engine.adapter {
            return Err(unusable(format!(
                "written by {} {}, this run is {} {}",
                rec.header.backend, rec.header.adapter, engine.backend, engine.adapter
            )));
        }
        let Some(chunk) = rec.chunks_of(super::format::ChunkKind::Keyframe).next() else {
            return Err(unusable("no keyframe in the file".into()));
        };
        let kf = Keyframe::decode(&chunk.payload).map_err(|e| unusable(e.to_string()))?;
        if kf.sim.t.abs() > 1e-9 {
            return Err(unusable(format!("the state is at t = {} s, not at the end of a relaxation", kf.sim.t)));
        }
        sim.restore(kf.sim.clone()).map_err(|e| unusable(e.to_string()))?;
        Ok(Some(Restored { file, snapshot: kf.sim, patient: kf.patient }))
    }

    /// Keeps `snapshot` (taken at the end of `scenario`'s relaxation on `engine`) with the patient
    /// then, written to a temporary file and renamed, so that a reader never sees half a file; then
    /// removes the oldest files beyond [`KEEP`]. Returns the file.
    pub fn store(
        &self,
        scenario: &Scenario,
        engine: &Engine,
        snapshot: &Snapshot,
        patient: Option<&Patient>,
    ) -> Result<PathBuf, CacheError> {
        let io = |source| CacheError::Io { dir: self.dir.display().to_string(), source };
        std::fs::create_dir_all(&self.dir).map_err(io)?;
        let file = self.path_for(scenario, engine);
        let tmp = file.with_extension(format!("tmp{}", std::process::id()));
        let written = (|| {
            let mut r = Recorder::create(&tmp, scenario, &engine.backend, &engine.adapter)?;
            let kf = Keyframe { sim: snapshot.clone(), patient: patient.cloned() };
            r.keyframe(snapshot.steps, snapshot.t, &kf)?;
            r.finish()?;
            Ok::<(), ReplayError>(())
        })();
        if let Err(e) = written {
            let _ = std::fs::remove_file(&tmp);
            return Err(e.into());
        }
        std::fs::rename(&tmp, &file).map_err(io)?;
        self.prune(&file);
        Ok(file)
    }

    /// Removes the oldest cached states beyond [`KEEP`] (never `keep`); failures are ignored (a
    /// cache that grows is not an error).
    /// Also removes temporary files more than an hour old (a writer that died before its rename).
    fn prune(&self, keep: &Path) {
        let Ok(entries) = std::fs::read_dir(&self.dir) else { return };
        let dated = |p: PathBuf| Some((std::fs::metadata(&p).ok()?.modified().ok()?, p));
        let (mut files, temporary): (Vec<_>, Vec<_>) = entries
            .filter_map(Result::ok)
            .map(|e| e.path())
            .filter(|p| p != keep)
            .filter_map(dated)
            .partition(|(_, p)| p.extension().is_some_and(|x| x == "pfrec"));
        files.sort_by_key(|f| std::cmp::Reverse(f.0));
        for (_, p) in files.iter().skip(KEEP.saturating_sub(1)) {
            let _ = std::fs::remove_file(p);
        }
        let stale = |t: &std::time::SystemTime| t.elapsed().is_ok_and(|age| age.as_secs() > 3600);
        for (_, p) in temporary.iter().filter(|(t, p)| stale(t) && is_temporary(p)) {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// FNV-1a 64 over the bytes of the scenario's surface meshes (`PerfusedMesh`): the scenario's text
/// names a mesh by its path only, and an edited mesh is another organ. An unreadable mesh counts as
/// empty (building the simulation reports it).
fn mesh_id(scenario: &Scenario) -> u64 {
    let mut bytes = Vec::new();
    for g in &scenario.particles {
        if let crate::scenario::Generator::PerfusedMesh { file, .. } = g {
            let path = scenario.base_dir.as_ref().map_or_else(|| PathBuf::from(file), |d| d.join(file));
            bytes.extend_from_slice(&fnv1a64(&std::fs::read(path).unwrap_or_default()).to_le_bytes());
        }
    }
    fnv1a64(&bytes)
}

/// A file [`RelaxedCache::store`] writes before renaming it (`NAME.tmpPID`).
fn is_temporary(p: &Path) -> bool {
    p.extension()
        .and_then(|x| x.to_str())
        .is_some_and(|x| x.starts_with("tmp") && x[3..].bytes().all(|b| b.is_ascii_digit()))
}

/// FNV-1a 64 of the running executable's bytes (read once per process); 0 when it cannot be read, so
/// that the key still holds the version, back-end and scenario.
pub fn build_id() -> u64 {
    static ID: std::sync::OnceLock<u64> = std::sync::OnceLock::new();
    *ID.get_or_init(|| std::env::current_exe().and_then(std::fs::read).map_or(0, |b| fnv1a64(&b)))
}

/// Relaxes `sim` (built from `scenario`, not yet stepped) as [`Simulation::relax`] does — or, unless
/// `fresh`, restores the state an earlier relaxation of the same scenario on the same engine reached
/// from `cache`, and keeps a new one there after relaxing. Returns the file restored from (also logged
/// at `info`). A cache
/// that cannot be read or written is logged and otherwise changes nothing: the relaxation runs.
pub fn relax_with_cache(
    cache: Option<&RelaxedCache>,
    fresh: bool,
    scenario: &Scenario,
    sim: &mut Simulation,
    progress: impl FnMut(f64),
) -> Result<Option<PathBuf>, crate::sim::SimError> {
    let relaxes = scenario.relaxation.as_ref().is_some_and(|r| r.duration > 0.0);
    let Some(cache) = cache.filter(|_| relaxes) else {
        sim.relax(progress)?;
        return Ok(None);
    };
    if !fresh {
        match cache.restore(scenario, sim) {
            Ok(Some(r)) => {
                log::info!("{}: relaxed state restored from {}", scenario.name, r.file.display());
                return Ok(Some(r.file));
            }
            Ok(None) => {}
            Err(e) => log::warn!("{e}"),
        }
    }
    sim.relax(progress)?;
    let kept = sim
        .snapshot()
        .map_err(|e| e.to_string())
        .and_then(|snap| cache.store(scenario, &Engine::of(sim), &snap, None).map_err(|e| e.to_string()));
    match kept {
        Ok(f) => log::info!("relaxed state kept in {}", f.display()),
        Err(e) => log::warn!("the relaxed state is not kept: {e}"),
    }
    Ok(None)
}
