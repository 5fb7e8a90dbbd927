//! Dynamic mode decomposition of SPH particle snapshots (thesis chapter 5, SPEC §8).
//!
//! Exact DMD (Schmid 2010; Kutz et al. 2016), following the thesis step by step:
//!
//! 1. snapshot matrices X = [x_1 … x_{m−1}], X' = [x_2 … x_m]                          (5.1), X' ≈ A X (5.2)
//! 2. thin SVD X = U Σ V*                                                             (5.3)
//! 3. rank-r truncation Ũ, Σ̃, Ṽ (numerical rank, user rank, or cumulative singular-value energy)
//! 4. Ã = Ũ* X' Ṽ Σ̃⁻¹                                                                 (5.4)
//! 5. Ã W = W Λ                                                                        (5.5)
//! 6. Φ = X' Ṽ Σ̃⁻¹ W, columns normalised to unit 2-norm                               (5.6)
//! 7. amplitudes a = argmin ‖Φ a − x_1‖₂ ("solving the initial value problem", §5.2)
//! 8. stabilisation μ = λ/|λ| for |λ| > 1 (§5.3.1)
//! 9. x̂(t) = Re Σ_j a_j φ_j μ_j^k, k = (t − t_1)/Δt_s (5.7, with the snapshot index as exponent, SPEC D-35);
//!    k may exceed m − 1 (prediction beyond the training window) or be fractional (ω = ln μ / Δt_s).
//!
//! No mean subtraction (SPEC §8.1): the time-mean configuration appears as a mode with λ ≈ 1.
//! The linear algebra (SVD, non-symmetric eigen-decomposition, products) is faer's.
//!
//! Beyond the thesis: [`AmplitudeFit::AllSnapshots`] (least-squares amplitudes over the whole record, opt-in),
//! [`DmdModel::is_oscillating`] (what "oscillating mode" means for [`DmdModel::dominant_frequency_hz`]), and the
//! per-particle position errors of [`position_errors`] for the §7.13/§7.14 acceptance checks.
//!
//! Entry point for the CLI `perfuse dmd FRAMES_DIR [--rank R | --energy E] [--out DIR]`: [`run_dmd`] with
//! [`rank_selection_from_cli`]; the frame interval is not stored in the frames and must be passed in.

use faer::{Mat, MatRef, c64};
use plotters::prelude::*;
use serde::Serialize;
use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};

// Path relative to this file; in the main crate (src/analysis/dmd.rs) it is "../../assets/fonts/DejaVuSansMono.ttf".
static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSansMono.ttf");
static FONT_ONCE: std::sync::Once = std::sync::Once::new();

/// Time columns reconstructed per matrix product (bounds the temporary n × block matrices).
const RECON_BLOCK: usize = 256;

// ---------------------------------------------------------------------------------------------------------------
// Errors
// ---------------------------------------------------------------------------------------------------------------

/// Everything that can go wrong; messages name the file / field and say how to fix it.
#[derive(Debug, thiserror::Error)]
pub enum DmdError {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(
        "no frame files named frame_NNNNN.csv in {}: point FRAMES_DIR at the --out directory of a `perfuse run` \
         whose scenario sets output.frame_interval",
        dir.display()
    )]
    NoFrames { dir: PathBuf },
    #[error(
        "{}: frame index {missing} is missing (found {before} and {after}); DMD needs frames at a uniform \
         interval: restore the missing file or pass a directory with a contiguous sequence",
        dir.display()
    )]
    FrameGap { dir: PathBuf, missing: u64, before: u64, after: u64 },
    #[error("{}: two files carry frame index {index} ({first} and {second}); keep only one", dir.display())]
    DuplicateFrameIndex { dir: PathBuf, index: u64, first: String, second: String },
    #[error(
        "{}: bad header `{found}`: missing column(s) {missing}; expected \
         `phase,id,x,y,z,vx,vy,vz,density,n_s,n_l,pressure` as written by `perfuse run`",
        file.display()
    )]
    BadHeader { file: PathBuf, found: String, missing: String },
    #[error("{}:{line}: row has {found} fields but the header has {expected}", file.display())]
    RowLength { file: PathBuf, line: usize, found: usize, expected: usize },
    #[error("{}:{line}: column `{column}`: cannot parse `{value}` as a number", file.display())]
    Parse { file: PathBuf, line: usize, column: String, value: String },
    #[error(
        "{}:{line}: column `{column}` is `{value}` (not finite): the run probably diverged; use frames \
         from before the divergence",
        file.display()
    )]
    NonFiniteValue { file: PathBuf, line: usize, column: String, value: String },
    #[error("{}:{line}: unknown phase `{value}` (expected `liquid` or `solid`)", file.display())]
    UnknownPhase { file: PathBuf, line: usize, value: String },
    #[error("{}:{line}: particle {particle} appears twice in the frame", file.display())]
    DuplicateParticle { file: PathBuf, line: usize, particle: ParticleKey },
    #[error(
        "{}: particle {particle} (present in {}) is missing: DMD needs a fixed particle set (no emitters or \
         sinks during the record); drop the frames from this one on",
        file.display(), first_file.display()
    )]
    MissingParticle { file: PathBuf, first_file: PathBuf, particle: ParticleKey },
    #[error(
        "{}: particle {particle} is not in the first frame {}: DMD needs a fixed particle set (no emitters \
         during the record); start the record after the last particle is added",
        file.display(), first_file.display()
    )]
    ExtraParticle { file: PathBuf, first_file: PathBuf, particle: ParticleKey },
    #[error("{}: the frame has no particle rows", file.display())]
    EmptyFrame { file: PathBuf },
    #[error("every selected component ({components}) is constant over all particles and frames: nothing to decompose")]
    AllConstant { components: String },
    #[error("frame interval {value} s is not a positive finite number: pass the run's output.frame_interval")]
    InvalidInterval { value: f64 },
    #[error("{got} snapshot(s): DMD needs at least 2 (X and X' of (5.1) need one column each); record more frames")]
    TooFewSnapshots { got: usize },
    #[error("times_s has {times} entries but there are {columns} snapshot columns")]
    TimeCountMismatch { times: usize, columns: usize },
    #[error("the snapshots have 0 components")]
    EmptyState,
    #[error("snapshot {index} has {len} components but snapshot 0 has {expected} (ragged snapshots)")]
    RaggedSnapshot { index: usize, len: usize, expected: usize },
    #[error("snapshot {index}, component {component} is {value} (not finite)")]
    NonFiniteSnapshot { index: usize, component: usize, value: f64 },
    #[error("times_s[{index}] = {value}: times must be finite and strictly increasing at a uniform interval")]
    BadTime { index: usize, value: f64 },
    #[error(
        "snapshot interval {index}→{} is {step} s but the mean interval is {dt} s: DMD needs uniformly \
         spaced snapshots; resample or drop the odd frame",
        index + 1
    )]
    NonUniformTimes { index: usize, step: f64, dt: f64 },
    #[error("rank 0 requested: the rank must be at least 1")]
    InvalidRank,
    #[error("energy threshold {value} is outside (0, 1]: pass e.g. --energy 0.99")]
    InvalidEnergy { value: f64 },
    #[error("both a rank and an energy threshold were given: choose one of --rank R and --energy E")]
    ConflictingSelection,
    #[error("the snapshot matrix is zero (largest singular value 0): nothing to decompose")]
    ZeroData,
    #[error("state dimension mismatch: the model has {expected} components, the snapshots have {got}")]
    DimensionMismatch { expected: usize, got: usize },
    #[error("the snapshots carry no particle layout (build them with load_frames to get per-particle errors)")]
    NoParticleLayout,
    #[error("linear algebra failed in {step}: {detail}")]
    Linalg { step: &'static str, detail: String },
    #[error("{}: cannot draw the chart: {message}", path.display())]
    Plot { path: PathBuf, message: String },
    #[error("{}: {source}", path.display())]
    Json {
        path: PathBuf,
        #[source]
        source: serde_json::Error,
    },
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> DmdError + '_ {
    move |source| DmdError::Io { path: path.to_path_buf(), source }
}

// ---------------------------------------------------------------------------------------------------------------
// Snapshots and frame loading
// ---------------------------------------------------------------------------------------------------------------

/// How the truncation rank r of step 3 is chosen.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum RankSelection {
    /// At most r modes (clamped to the numerical rank of X).
    Rank(usize),
    /// Smallest r with Σ_{k≤r} σ_k² / Σ_k σ_k² ≥ threshold, threshold ∈ (0, 1] (reduced-order model, §5.3.1).
    Energy(f64),
    /// The numerical rank: σ_k > σ_1 · max(n, m−1) · ε (SPEC §8.2 step 3 default; the thesis's full model).
    Full,
}

impl fmt::Display for RankSelection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RankSelection::Rank(r) => write!(f, "rank {r}"),
            RankSelection::Energy(e) => write!(f, "energy {e}"),
            RankSelection::Full => write!(f, "full (numerical rank)"),
        }
    }
}

/// Maps the CLI flags `--rank R` / `--energy E` (mutually exclusive; neither = full numerical rank).
pub fn rank_selection_from_cli(rank: Option<usize>, energy: Option<f64>) -> Result<RankSelection, DmdError> {
    match (rank, energy) {
        (Some(_), Some(_)) => Err(DmdError::ConflictingSelection),
        (Some(0), None) => Err(DmdError::InvalidRank),
        (Some(r), None) => Ok(RankSelection::Rank(r)),
        (None, Some(e)) if !(e > 0.0 && e <= 1.0) => Err(DmdError::InvalidEnergy { value: e }),
        (None, Some(e)) => Ok(RankSelection::Energy(e)),
        (None, None) => Ok(RankSelection::Full),
    }
}

/// Particle phase as written in the frame CSV.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub enum Phase {
    Liquid,
    Solid,
}

/// Stable particle identity across frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct ParticleKey {
    pub phase: Phase,
    pub id: u64,
}

impl fmt::Display for ParticleKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = match self.phase {
            Phase::Liquid => "liquid",
            Phase::Solid => "solid",
        };
        write!(f, "{p} id {}", self.id)
    }
}

/// One per-particle field of the state vector (Table 5.1: positions and/or velocities).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum Component {
    X,
    Y,
    Z,
    Vx,
    Vy,
    Vz,
}

impl Component {
    pub const POSITIONS: [Component; 3] = [Component::X, Component::Y, Component::Z];
    pub const ALL: [Component; 6] =
        [Component::X, Component::Y, Component::Z, Component::Vx, Component::Vy, Component::Vz];

    /// CSV column name.
    pub fn column(self) -> &'static str {
        match self {
            Component::X => "x",
            Component::Y => "y",
            Component::Z => "z",
            Component::Vx => "vx",
            Component::Vy => "vy",
            Component::Vz => "vz",
        }
    }

    pub fn is_position(self) -> bool {
        matches!(self, Component::X | Component::Y | Component::Z)
    }
}

/// Meaning of the state-vector entries: particle-major, entry `p * components.len() + c` is component `c` of
/// particle `particles[p]`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct StateLayout {
    pub particles: Vec<ParticleKey>,
    pub components: Vec<Component>,
    /// Components left out because they were constant over all particles and frames (e.g. z of a 2-D run),
    /// with that constant value.
    pub dropped: Vec<(Component, f64)>,
    /// Frame files left out: `perfuse run` writes its final state once more after the last regular frame when
    /// the run ends just past a frame time; that trailing copy (identical to the frame before it, and not at
    /// the next frame time) is dropped.
    pub dropped_frames: Vec<String>,
}

/// Snapshot sequence x_1 … x_m (5.1) at uniform times.
#[derive(Clone, Debug, Default)]
pub struct Snapshots {
    pub times_s: Vec<f64>,
    /// One state vector per time.
    pub columns: Vec<Vec<f64>>,
    /// Per-particle layout when the snapshots come from frames; `None` for generic state vectors.
    pub layout: Option<StateLayout>,
}

impl Snapshots {
    /// Generic state vectors (no particle layout).
    pub fn new(times_s: Vec<f64>, columns: Vec<Vec<f64>>) -> Self {
        Snapshots { times_s, columns, layout: None }
    }

    /// Generic state vectors at t_k = k · dt.
    pub fn uniform(dt_s: f64, columns: Vec<Vec<f64>>) -> Self {
        let times_s = (0..columns.len()).map(|k| k as f64 * dt_s).collect();
        Snapshots::new(times_s, columns)
    }

    pub fn len(&self) -> usize {
        self.columns.len()
    }

    pub fn is_empty(&self) -> bool {
        self.columns.is_empty()
    }

    pub fn state_dim(&self) -> usize {
        self.columns.first().map_or(0, Vec::len)
    }

    /// Snapshots `range` (e.g. a training window `0..k` and a test window `k..m` for prediction checks).
    pub fn slice(&self, range: std::ops::Range<usize>) -> Snapshots {
        let end = range.end.min(self.columns.len());
        let start = range.start.min(end);
        Snapshots {
            times_s: self.times_s.get(start..end).map(<[f64]>::to_vec).unwrap_or_default(),
            columns: self.columns[start..end].to_vec(),
            layout: self.layout.clone(),
        }
    }
}

/// Which per-particle fields make the state vector (Table 5.1: case 3 = positions only, the thesis's choice;
/// case 1 = positions + velocities).
#[derive(Clone, Copy, Debug, Default)]
pub struct FrameFields {
    pub velocities: bool,
}

/// Loads `frame_NNNNN.csv` files of a `perfuse run` output directory. Frame k lies at t = NNNNN · interval.
/// Particles are aligned by (phase, id) and ordered liquid-then-solid by id. Positions (and velocities when
/// asked) of every particle form the state; components constant over all particles and frames (z, vz of a
/// 2-D run) are dropped and recorded in [`StateLayout::dropped`].
pub fn load_frames(dir: &Path, frame_interval_s: f64, fields: FrameFields) -> Result<Snapshots, DmdError> {
    let comps: &[Component] = if fields.velocities { &Component::ALL } else { &Component::POSITIONS };
    load_impl(dir, frame_interval_s, comps, true)
}

/// Like [`load_frames`] with an explicit component list (e.g. `[Vx, Vy]` = Table 5.1 case 4); nothing is dropped.
pub fn load_frames_components(
    dir: &Path,
    frame_interval_s: f64,
    components: &[Component],
) -> Result<Snapshots, DmdError> {
    load_impl(dir, frame_interval_s, components, false)
}

/// Frame files of `dir` sorted by index; errors on gaps and duplicates.
pub fn list_frames(dir: &Path) -> Result<Vec<(u64, PathBuf)>, DmdError> {
    let rd = std::fs::read_dir(dir).map_err(io_err(dir))?;
    let mut frames: Vec<(u64, PathBuf)> = Vec::new();
    for entry in rd {
        let entry = entry.map_err(io_err(dir))?;
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let Some(digits) = name.strip_prefix("frame_").and_then(|s| s.strip_suffix(".csv")) else { continue };
        if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
            continue;
        }
        let Ok(index) = digits.parse::<u64>() else { continue };
        frames.push((index, entry.path()));
    }
    if frames.is_empty() {
        return Err(DmdError::NoFrames { dir: dir.to_path_buf() });
    }
    frames.sort();
    for w in frames.windows(2) {
        let ((i0, p0), (i1, p1)) = (&w[0], &w[1]);
        if i1 == i0 {
            let name = |p: &PathBuf| p.file_name().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
            return Err(DmdError::DuplicateFrameIndex {
                dir: dir.to_path_buf(),
                index: *i0,
                first: name(p0),
                second: name(p1),
            });
        }
        if *i1 != i0 + 1 {
            return Err(DmdError::FrameGap { dir: dir.to_path_buf(), missing: i0 + 1, before: *i0, after: *i1 });
        }
    }
    Ok(frames)
}

struct FrameData {
    /// (particle, values in `comps` order), in file order.
    rows: Vec<(ParticleKey, usize, Vec<f64>)>,
}

fn parse_frame(path: &Path, comps: &[Component]) -> Result<FrameData, DmdError> {
    let text = std::fs::read_to_string(path).map_err(io_err(path))?;
    let mut lines = text.lines().enumerate();
    let header = lines.next().map(|(_, l)| l.trim()).unwrap_or("");
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let find = |n: &str| names.iter().position(|h| *h == n);
    let mut missing = Vec::new();
    let phase_col = find("phase");
    let id_col = find("id");
    if phase_col.is_none() {
        missing.push("phase");
    }
    if id_col.is_none() {
        missing.push("id");
    }
    let mut comp_cols = Vec::with_capacity(comps.len());
    for c in comps {
        match find(c.column()) {
            Some(k) => comp_cols.push(k),
            None => missing.push(c.column()),
        }
    }
    let (Some(phase_col), Some(id_col)) = (phase_col, id_col) else {
        return Err(DmdError::BadHeader {
            file: path.to_path_buf(),
            found: header.into(),
            missing: missing.join(", "),
        });
    };
    if !missing.is_empty() {
        return Err(DmdError::BadHeader {
            file: path.to_path_buf(),
            found: header.into(),
            missing: missing.join(", "),
        });
    }
    let mut rows = Vec::new();
    for (ln, line) in lines {
        let line_no = ln + 1;
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != names.len() {
            return Err(DmdError::RowLength {
                file: path.to_path_buf(),
                line: line_no,
                found: fields.len(),
                expected: names.len(),
            });
        }
        let phase = match fields[phase_col] {
            "liquid" => Phase::Liquid,
            "solid" => Phase::Solid,
            other => {
                return Err(DmdError::UnknownPhase { file: path.to_path_buf(), line: line_no, value: other.into() });
            }
        };
        let id = fields[id_col].parse::<u64>().map_err(|_| DmdError::Parse {
            file: path.to_path_buf(),
            line: line_no,
            column: "id".into(),
            value: fields[id_col].into(),
        })?;
        let mut vals = Vec::with_capacity(comps.len());
        for (c, &k) in comps.iter().zip(&comp_cols) {
            let s = fields[k];
            let v = s.parse::<f64>().map_err(|_| DmdError::Parse {
                file: path.to_path_buf(),
                line: line_no,
                column: c.column().into(),
                value: s.into(),
            })?;
            if !v.is_finite() {
                return Err(DmdError::NonFiniteValue {
                    file: path.to_path_buf(),
                    line: line_no,
                    column: c.column().into(),
                    value: s.into(),
                });
            }
            vals.push(v);
        }
        rows.push((ParticleKey { phase, id }, line_no, vals));
    }
    if rows.is_empty() {
        return Err(DmdError::EmptyFrame { file: path.to_path_buf() });
    }
    Ok(FrameData { rows })
}

fn load_impl(dir: &Path, dt: f64, comps: &[Component], drop_constant: bool) -> Result<Snapshots, DmdError> {
    if !(dt.is_finite() && dt > 0.0) {
        return Err(DmdError::InvalidInterval { value: dt });
    }
    let frames = list_frames(dir)?;
    let nc = comps.len();
    let mut particles: Vec<ParticleKey> = Vec::new();
    let mut index: HashMap<ParticleKey, usize> = HashMap::new();
    let mut columns: Vec<Vec<f64>> = Vec::with_capacity(frames.len());
    let first_file = frames[0].1.clone();
    for (fi, (_, path)) in frames.iter().enumerate() {
        let data = parse_frame(path, comps)?;
        if fi == 0 {
            let mut keys: Vec<(ParticleKey, usize)> = data.rows.iter().map(|(k, l, _)| (*k, *l)).collect();
            keys.sort();
            for w in keys.windows(2) {
                if w[0].0 == w[1].0 {
                    return Err(DmdError::DuplicateParticle {
                        file: path.clone(),
                        line: w[0].1.max(w[1].1),
                        particle: w[0].0,
                    });
                }
            }
            particles = keys.into_iter().map(|(k, _)| k).collect();
            index = particles.iter().enumerate().map(|(i, k)| (*k, i)).collect();
        }
        let np = particles.len();
        let mut col = vec![0.0; np * nc];
        let mut seen = vec![false; np];
        for (key, line, vals) in &data.rows {
            let Some(&p) = index.get(key) else {
                return Err(DmdError::ExtraParticle {
                    file: path.clone(),
                    first_file: first_file.clone(),
                    particle: *key,
                });
            };
            if seen[p] {
                return Err(DmdError::DuplicateParticle { file: path.clone(), line: *line, particle: *key });
            }
            seen[p] = true;
            col[p * nc..(p + 1) * nc].copy_from_slice(vals);
        }
        if let Some(p) = seen.iter().position(|s| !s) {
            return Err(DmdError::MissingParticle {
                file: path.clone(),
                first_file: first_file.clone(),
                particle: particles[p],
            });
        }
        columns.push(col);
    }
    let mut frames = frames;
    let mut dropped_frames = Vec::new();
    if columns.len() > 2 && columns[columns.len() - 1] == columns[columns.len() - 2] {
        columns.pop();
        if let Some((_, p)) = frames.pop() {
            dropped_frames.push(p.file_name().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default());
        }
    }
    let mut keep: Vec<usize> = (0..nc).collect();
    let mut dropped = Vec::new();
    if drop_constant {
        keep.clear();
        for c in 0..nc {
            let v0 = columns[0][c];
            let tol = 1e-12 * v0.abs().max(1.0);
            let constant = columns.iter().all(|col| col.iter().skip(c).step_by(nc).all(|v| (v - v0).abs() <= tol));
            if constant {
                dropped.push((comps[c], v0));
            } else {
                keep.push(c);
            }
        }
        if keep.is_empty() {
            let names: Vec<&str> = comps.iter().map(|c| c.column()).collect();
            return Err(DmdError::AllConstant { components: names.join(", ") });
        }
        if keep.len() < nc {
            for col in &mut columns {
                let reduced: Vec<f64> =
                    (0..particles.len()).flat_map(|p| keep.iter().map(move |&c| p * nc + c)).map(|i| col[i]).collect();
                *col = reduced;
            }
        }
    }
    let times_s = frames.iter().map(|(i, _)| *i as f64 * dt).collect();
    let layout =
        StateLayout { particles, components: keep.iter().map(|&c| comps[c]).collect(), dropped, dropped_frames };
    Ok(Snapshots { times_s, columns, layout: Some(layout) })
}

// ---------------------------------------------------------------------------------------------------------------
// Decomposition (5.1)–(5.6)
// ---------------------------------------------------------------------------------------------------------------

/// Checks the snapshots; returns (n, m, t_1, Δt_s).
fn validate(s: &Snapshots) -> Result<(usize, usize, f64, f64), DmdError> {
    let m = s.columns.len();
    if s.times_s.len() != m {
        return Err(DmdError::TimeCountMismatch { times: s.times_s.len(), columns: m });
    }
    if m < 2 {
        return Err(DmdError::TooFewSnapshots { got: m });
    }
    let n = s.columns[0].len();
    if n == 0 {
        return Err(DmdError::EmptyState);
    }
    for (k, col) in s.columns.iter().enumerate() {
        if col.len() != n {
            return Err(DmdError::RaggedSnapshot { index: k, len: col.len(), expected: n });
        }
        if let Some(i) = col.iter().position(|v| !v.is_finite()) {
            return Err(DmdError::NonFiniteSnapshot { index: k, component: i, value: col[i] });
        }
    }
    validate_times(&s.times_s).map(|(t0, dt)| (n, m, t0, dt))
}

fn validate_times(t: &[f64]) -> Result<(f64, f64), DmdError> {
    let m = t.len();
    if let Some(k) = t.iter().position(|v| !v.is_finite()) {
        return Err(DmdError::BadTime { index: k, value: t[k] });
    }
    let dt = (t[m - 1] - t[0]) / (m - 1) as f64;
    if !(dt > 0.0 && dt.is_finite()) {
        return Err(DmdError::BadTime { index: m - 1, value: t[m - 1] });
    }
    for k in 0..m - 1 {
        let step = t[k + 1] - t[k];
        if step <= 0.0 {
            return Err(DmdError::BadTime { index: k + 1, value: t[k + 1] });
        }
        if (step - dt).abs() > 1e-6 * dt {
            return Err(DmdError::NonUniformTimes { index: k, step, dt });
        }
    }
    Ok((t[0], dt))
}

/// The SVD of X (5.3) with the data, computed once and reused for several ranks (reduced-order models).
pub struct Decomposition {
    /// [x_1 … x_m], n × m; X = first m−1 columns, X' = last m−1 columns (5.1).
    data: Mat<f64>,
    u: Mat<f64>,
    v: Mat<f64>,
    sigma: Vec<f64>,
    numerical_rank: usize,
    t0: f64,
    dt: f64,
}

impl Decomposition {
    /// Validates the snapshots and takes the thin SVD X = U Σ V* (5.3).
    pub fn new(s: &Snapshots) -> Result<Self, DmdError> {
        let (n, m, t0, dt) = validate(s)?;
        let data = Mat::<f64>::from_fn(n, m, |i, j| s.columns[j][i]);
        let x = data.as_ref().subcols(0, m - 1);
        let svd = x.thin_svd().map_err(|e| DmdError::Linalg { step: "SVD of X (5.3)", detail: format!("{e:?}") })?;
        let sigma: Vec<f64> = svd.S().column_vector().iter().copied().collect();
        let s1 = sigma.first().copied().unwrap_or(0.0);
        if s1.is_nan() || s1 <= 0.0 {
            return Err(DmdError::ZeroData);
        }
        let tol = s1 * (n.max(m - 1) as f64) * f64::EPSILON;
        let numerical_rank = sigma.iter().take_while(|&&v| v > tol).count();
        Ok(Decomposition { data, u: svd.U().to_owned(), v: svd.V().to_owned(), sigma, numerical_rank, t0, dt })
    }

    /// Singular values of X, nonincreasing.
    pub fn singular_values(&self) -> &[f64] {
        &self.sigma
    }

    /// Number of singular values above σ_1 · max(n, m−1) · ε.
    pub fn numerical_rank(&self) -> usize {
        self.numerical_rank
    }

    /// Rank r of step 3 (never above the numerical rank, where Σ̃⁻¹ in (5.4) would amplify round-off).
    pub fn select_rank(&self, sel: RankSelection) -> Result<usize, DmdError> {
        match sel {
            RankSelection::Rank(0) => Err(DmdError::InvalidRank),
            RankSelection::Rank(r) => Ok(r.min(self.numerical_rank)),
            RankSelection::Energy(e) if !(e > 0.0 && e <= 1.0) => Err(DmdError::InvalidEnergy { value: e }),
            RankSelection::Energy(e) => {
                let cum = cumulative_energy(&self.sigma);
                let r = cum.iter().position(|&c| c >= e - 1e-12).map_or(cum.len(), |k| k + 1);
                Ok(r.clamp(1, self.numerical_rank))
            }
            RankSelection::Full => Ok(self.numerical_rank),
        }
    }

    /// Steps 3–7 at the selected rank, amplitudes from x_1 (the thesis's initial value problem).
    pub fn model(&self, sel: RankSelection) -> Result<DmdModel, DmdError> {
        self.model_with(sel, AmplitudeFit::InitialCondition)
    }

    /// Steps 3–7 at the selected rank with the chosen amplitude fit.
    pub fn model_with(&self, sel: RankSelection, amplitudes: AmplitudeFit) -> Result<DmdModel, DmdError> {
        let r = self.select_rank(sel)?;
        self.model_at_rank(r, sel, amplitudes)
    }

    fn model_at_rank(
        &self,
        r: usize,
        selection: RankSelection,
        amplitude_fit: AmplitudeFit,
    ) -> Result<DmdModel, DmdError> {
        let n = self.data.nrows();
        let m = self.data.ncols();
        let x_next = self.data.as_ref().subcols(1, m - 1);
        let u_r = self.u.as_ref().subcols(0, r);
        let v_r = self.v.as_ref().subcols(0, r);
        // B = X' Ṽ Σ̃⁻¹ (n × r), shared by (5.4) and (5.6).
        let mut b: Mat<f64> = x_next * v_r;
        for j in 0..r {
            let inv = 1.0 / self.sigma[j];
            b.col_mut(j).iter_mut().for_each(|x| *x *= inv);
        }
        // (5.4) Ã = Ũ* X' Ṽ Σ̃⁻¹.
        let a_tilde: Mat<f64> = u_r.transpose() * b.as_ref();
        if a_tilde.col_iter().any(|c| c.iter().any(|v| !v.is_finite())) {
            return Err(DmdError::Linalg { step: "projected operator (5.4)", detail: "non-finite entries".into() });
        }
        // (5.5) Ã W = W Λ (general real matrix: complex eigenpairs).
        let eig = a_tilde
            .eigen()
            .map_err(|e| DmdError::Linalg { step: "eigen-decomposition of Ã (5.5)", detail: format!("{e:?}") })?;
        let lambda: Vec<c64> = eig.S().column_vector().iter().copied().collect();
        let w = eig.U();
        let w_re = Mat::<f64>::from_fn(r, r, |i, j| w[(i, j)].re);
        let w_im = Mat::<f64>::from_fn(r, r, |i, j| w[(i, j)].im);
        // (5.6) Φ = X' Ṽ Σ̃⁻¹ W.
        let mut phi_re: Mat<f64> = b.as_ref() * w_re.as_ref();
        let mut phi_im: Mat<f64> = b.as_ref() * w_im.as_ref();
        let norms: Vec<f64> = (0..r).map(|j| col_norm(phi_re.as_ref(), phi_im.as_ref(), j)).collect();
        let max_norm = norms.iter().copied().fold(0.0, f64::max);
        let lam_max = lambda.iter().map(|l| l.norm()).fold(0.0, f64::max);
        // λ_j = 0 makes the exact mode vanish: use the projected mode Ũ w_j instead (SPEC §8.2).
        for j in 0..r {
            if lambda[j].norm() <= 1e-12 * lam_max.max(1.0) || norms[j] <= 1e-12 * max_norm {
                let pr: Mat<f64> = u_r * w_re.as_ref().subcols(j, 1);
                let pi: Mat<f64> = u_r * w_im.as_ref().subcols(j, 1);
                phi_re.col_mut(j).copy_from(pr.col(0));
                phi_im.col_mut(j).copy_from(pi.col(0));
            }
        }
        // Unit 2-norm modes; the scale goes into a_j (SPEC §8.2, D-35).
        for j in 0..r {
            let nj = col_norm(phi_re.as_ref(), phi_im.as_ref(), j);
            if nj > 0.0 && nj.is_finite() {
                let inv = 1.0 / nj;
                phi_re.col_mut(j).iter_mut().for_each(|x| *x *= inv);
                phi_im.col_mut(j).iter_mut().for_each(|x| *x *= inv);
            }
        }
        // Amplitudes: a = argmin ‖Φ a − x_1‖₂ ("initial value problem", §5.2), minimum-norm via the SVD of Φ.
        let phi_c = Mat::<c64>::from_fn(n, r, |i, j| c64::new(phi_re[(i, j)], phi_im[(i, j)]));
        let svd = phi_c
            .thin_svd()
            .map_err(|e| DmdError::Linalg { step: "amplitudes (SVD of Φ)", detail: format!("{e:?}") })?;
        let x1 = Mat::<c64>::from_fn(n, 1, |i, _| c64::new(self.data[(i, 0)], 0.0));
        let uhx: Mat<c64> = svd.U().adjoint() * x1.as_ref();
        let sv: Vec<f64> = svd.S().column_vector().iter().map(|z| z.re).collect();
        let cut = sv.first().copied().unwrap_or(0.0) * (n.max(r) as f64) * f64::EPSILON;
        let scaled = Mat::<c64>::from_fn(sv.len(), 1, |k, _| {
            if sv[k] > cut { uhx[(k, 0)] * (1.0 / sv[k]) } else { c64::new(0.0, 0.0) }
        });
        let amp_m: Mat<c64> = svd.V() * scaled.as_ref();
        let amplitudes: Vec<c64> = (0..r).map(|j| amp_m[(j, 0)]).collect();
        let log_eigenvalues = lambda.iter().map(|&l| complex_ln(l)).collect();
        let mut model = DmdModel {
            rank: r,
            selection,
            amplitude_fit: AmplitudeFit::InitialCondition,
            numerical_rank: self.numerical_rank,
            dt: self.dt,
            t0: self.t0,
            n_train: m,
            eigenvalues: lambda,
            log_eigenvalues,
            amplitudes,
            phi_re,
            phi_im,
            singular_values: self.sigma.clone(),
        };
        if amplitude_fit == AmplitudeFit::AllSnapshots {
            let times: Vec<f64> = (0..m).map(|k| self.t0 + k as f64 * self.dt).collect();
            model.fit_amplitudes_all(self.data.as_ref(), &times, true)?;
        }
        model.sort_by_amplitude();
        Ok(model)
    }
}

fn col_norm(re: MatRef<'_, f64>, im: MatRef<'_, f64>, j: usize) -> f64 {
    let a = re.col(j).norm_l2();
    let b = im.col(j).norm_l2();
    a.hypot(b)
}

/// ln μ with |μ| floored at the smallest normal f64 (λ = 0 → growth rate ≈ −708/Δt_s, finite).
fn complex_ln(l: c64) -> c64 {
    let r = l.norm().max(f64::MIN_POSITIVE);
    c64::new(r.ln(), l.im.atan2(l.re))
}

/// Exact DMD (5.1)–(5.6) with amplitudes from x_1 (thesis §5.2); see the module documentation.
pub fn fit(s: &Snapshots, sel: RankSelection) -> Result<DmdModel, DmdError> {
    Decomposition::new(s)?.model(sel)
}

/// [`fit`] with a choice of amplitude fit.
pub fn fit_with(s: &Snapshots, sel: RankSelection, amplitudes: AmplitudeFit) -> Result<DmdModel, DmdError> {
    Decomposition::new(s)?.model_with(sel, amplitudes)
}

/// How the amplitudes a_j are obtained.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub enum AmplitudeFit {
    /// a = argmin ‖Φ a − x_1‖₂: the thesis's "initial value problem" (§5.2, SPEC §8.2 step 7). Default.
    #[default]
    InitialCondition,
    /// a = argmin Σ_k ‖x_k − Re Σ_j a_j φ_j μ_j^k‖² over all training snapshots with the stabilised μ
    /// ("optimal amplitudes", Jovanović, Schmid & Nichols 2014). Not in the thesis; spreads the error of a
    /// nonlinear record over the window instead of letting it grow from x_1.
    AllSnapshots,
}

impl fmt::Display for AmplitudeFit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AmplitudeFit::InitialCondition => write!(f, "initial condition x_1"),
            AmplitudeFit::AllSnapshots => write!(f, "all snapshots (optimal amplitudes)"),
        }
    }
}

/// E(r) = Σ_{k≤r} σ_k² / Σ_k σ_k² for r = 1 … len (the POD energy the thesis borrows, Fig. 5.9).
pub fn cumulative_energy(singular_values: &[f64]) -> Vec<f64> {
    let total: f64 = singular_values.iter().map(|s| s * s).sum();
    if !(total > 0.0 && total.is_finite()) {
        return vec![0.0; singular_values.len()];
    }
    let mut acc = 0.0;
    singular_values
        .iter()
        .map(|s| {
            acc += s * s;
            (acc / total).min(1.0)
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------------------------
// Model
// ---------------------------------------------------------------------------------------------------------------

/// A fitted DMD model. Modes are ordered by amplitude |a_j|, largest first.
#[derive(Clone, Debug)]
pub struct DmdModel {
    rank: usize,
    selection: RankSelection,
    amplitude_fit: AmplitudeFit,
    numerical_rank: usize,
    dt: f64,
    t0: f64,
    n_train: usize,
    eigenvalues: Vec<c64>,
    log_eigenvalues: Vec<c64>,
    amplitudes: Vec<c64>,
    /// Φ (5.6), unit-norm columns, real and imaginary parts (n × r).
    phi_re: Mat<f64>,
    phi_im: Mat<f64>,
    singular_values: Vec<f64>,
}

/// One mode's scalars, for tables and JSON.
#[derive(Clone, Debug, Serialize)]
pub struct ModeSummary {
    pub index: usize,
    pub eigenvalue: [f64; 2],
    pub abs_eigenvalue: f64,
    pub frequency_hz: f64,
    pub growth_rate: f64,
    /// |a_j| (unit-norm modes).
    pub amplitude: f64,
    /// |a_j| · sqrt(mean over the training window of |μ_j|^{2k}), μ_j the stabilised eigenvalue: the mode's RMS
    /// size over the record in the stabilised reconstruction, small for fast-decaying modes whatever their |a_j|
    /// (what [`DmdModel::dominant_frequency_hz`] ranks by).
    pub window_rms_amplitude: f64,
    /// See [`DmdModel::is_oscillating`].
    pub oscillating: bool,
}

impl DmdModel {
    /// Number of modes r.
    pub fn rank(&self) -> usize {
        self.rank
    }

    /// How the rank was chosen.
    pub fn selection(&self) -> RankSelection {
        self.selection
    }

    /// How the amplitudes were obtained.
    pub fn amplitude_fit(&self) -> AmplitudeFit {
        self.amplitude_fit
    }

    /// Refits the amplitudes over all snapshots of `s` (any uniform or non-uniform times, typically the
    /// training window) so that the (5.7) reconstruction, stabilised or not, is least-squares optimal
    /// ([`AmplitudeFit::AllSnapshots`]). Modes are re-sorted by the new amplitudes.
    pub fn refit_amplitudes(&mut self, s: &Snapshots, stabilise: bool) -> Result<(), DmdError> {
        check_dims(self, s)?;
        if s.is_empty() {
            return Err(DmdError::TooFewSnapshots { got: 0 });
        }
        if let Some((k, i)) =
            s.columns.iter().enumerate().find_map(|(k, c)| c.iter().position(|v| !v.is_finite()).map(|i| (k, i)))
        {
            return Err(DmdError::NonFiniteSnapshot { index: k, component: i, value: s.columns[k][i] });
        }
        let n = self.state_dim();
        let data = Mat::<f64>::from_fn(n, s.len(), |i, j| s.columns[j][i]);
        self.fit_amplitudes_all(data.as_ref(), &s.times_s, stabilise)?;
        self.sort_by_amplitude();
        Ok(())
    }

    /// Normal equations of min Σ_k ‖x_k − Φ diag(a) v_k‖², v_jk = μ_j^{k}: P a = q with
    /// P = (Φ*Φ) ∘ conj(V V*), q_j = Σ_k conj(v_jk) (Φ* x_k)_j; solved by a truncated pseudo-inverse.
    fn fit_amplitudes_all(&mut self, data: MatRef<'_, f64>, times: &[f64], stabilise: bool) -> Result<(), DmdError> {
        let r = self.rank;
        let expo = self.exponents(stabilise);
        let (pr, pi) = (self.phi_re.as_ref(), self.phi_im.as_ref());
        // Φ*Φ = (ReᵀRe + ImᵀIm) + i (ReᵀIm − ImᵀRe).
        let g_re: Mat<f64> = pr.transpose() * pr + pi.transpose() * pi;
        let g_im: Mat<f64> = pr.transpose() * pi - pi.transpose() * pr;
        let mut vv = Mat::<c64>::zeros(r, r);
        let mut q = vec![c64::new(0.0, 0.0); r];
        for (b, chunk) in times.chunks(RECON_BLOCK).enumerate() {
            let k0 = b * RECON_BLOCK;
            let v = Mat::<c64>::from_fn(r, chunk.len(), |j, c| {
                let k = (chunk[c] - self.t0) / self.dt;
                if k == 0.0 { c64::new(1.0, 0.0) } else { (expo[j] * k).exp() }
            });
            vv += v.as_ref() * v.as_ref().adjoint();
            let xb = data.subcols(k0, chunk.len());
            // Φ* X_b = Reᵀ X_b − i Imᵀ X_b.
            let h_re: Mat<f64> = pr.transpose() * xb;
            let h_im: Mat<f64> = pi.transpose() * xb;
            for (j, qj) in q.iter_mut().enumerate() {
                for c in 0..chunk.len() {
                    *qj += v[(j, c)].conj() * c64::new(h_re[(j, c)], -h_im[(j, c)]);
                }
            }
        }
        let p = Mat::<c64>::from_fn(r, r, |i, j| c64::new(g_re[(i, j)], g_im[(i, j)]) * vv[(i, j)].conj());
        let svd = p
            .thin_svd()
            .map_err(|e| DmdError::Linalg { step: "amplitudes (normal equations)", detail: format!("{e:?}") })?;
        let sv: Vec<f64> = svd.S().column_vector().iter().map(|z| z.re).collect();
        let cut = sv.first().copied().unwrap_or(0.0) * r as f64 * f64::EPSILON;
        let qm = Mat::<c64>::from_fn(r, 1, |j, _| q[j]);
        let uhq: Mat<c64> = svd.U().adjoint() * qm.as_ref();
        let scaled = Mat::<c64>::from_fn(sv.len(), 1, |k, _| {
            if sv[k] > cut { uhq[(k, 0)] * (1.0 / sv[k]) } else { c64::new(0.0, 0.0) }
        });
        let a: Mat<c64> = svd.V() * scaled.as_ref();
        if (0..r).any(|j| !(a[(j, 0)].re.is_finite() && a[(j, 0)].im.is_finite())) {
            return Err(DmdError::Linalg { step: "amplitudes (normal equations)", detail: "non-finite result".into() });
        }
        self.amplitudes = (0..r).map(|j| a[(j, 0)]).collect();
        self.amplitude_fit = AmplitudeFit::AllSnapshots;
        Ok(())
    }

    /// Orders the modes by |a_j|, largest first.
    fn sort_by_amplitude(&mut self) {
        let r = self.rank;
        let n = self.state_dim();
        let mut order: Vec<usize> = (0..r).collect();
        order.sort_by(|&i, &j| self.amplitudes[j].norm().total_cmp(&self.amplitudes[i].norm()).then(i.cmp(&j)));
        self.phi_re = Mat::<f64>::from_fn(n, r, |i, j| self.phi_re[(i, order[j])]);
        self.phi_im = Mat::<f64>::from_fn(n, r, |i, j| self.phi_im[(i, order[j])]);
        self.eigenvalues = order.iter().map(|&j| self.eigenvalues[j]).collect();
        self.log_eigenvalues = order.iter().map(|&j| self.log_eigenvalues[j]).collect();
        self.amplitudes = order.iter().map(|&j| self.amplitudes[j]).collect();
    }

    /// Numerical rank of X (the upper bound for r).
    pub fn numerical_rank(&self) -> usize {
        self.numerical_rank
    }

    /// Snapshot interval Δt_s.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Time of the first training snapshot (k = 0 in (5.7)).
    pub fn t0(&self) -> f64 {
        self.t0
    }

    /// Number of training snapshots m.
    pub fn n_train(&self) -> usize {
        self.n_train
    }

    /// State dimension n.
    pub fn state_dim(&self) -> usize {
        self.phi_re.nrows()
    }

    /// Discrete-time eigenvalues λ_j (5.5) as (re, im).
    pub fn eigenvalues(&self) -> Vec<(f64, f64)> {
        self.eigenvalues.iter().map(|l| (l.re, l.im)).collect()
    }

    /// Eigenvalues after the §5.3.1 modification μ = λ/|λ| for |λ| > 1.
    pub fn stabilised_eigenvalues(&self) -> Vec<(f64, f64)> {
        self.eigenvalues
            .iter()
            .map(|l| {
                let a = l.norm();
                if a > 1.0 { (l.re / a, l.im / a) } else { (l.re, l.im) }
            })
            .collect()
    }

    /// Number of eigenvalues with |λ| > 1 (red in Figs. 5.3, 5.10, 5.13).
    pub fn n_unstable(&self) -> usize {
        self.eigenvalues.iter().filter(|l| l.norm() > 1.0).count()
    }

    /// f_j = Im(ln λ_j) / (2π Δt_s) in Hz (SPEC §8.2 step 10); conjugate pairs give ±f.
    pub fn frequencies_hz(&self) -> Vec<f64> {
        self.log_eigenvalues.iter().map(|w| w.im / (2.0 * std::f64::consts::PI * self.dt)).collect()
    }

    /// g_j = Re(ln λ_j) / Δt_s [1/s].
    pub fn growth_rates(&self) -> Vec<f64> {
        self.log_eigenvalues.iter().map(|w| w.re / self.dt).collect()
    }

    /// |a_j| (modes have unit 2-norm, so this is also |a_j|·‖φ_j‖).
    pub fn amplitudes(&self) -> Vec<f64> {
        self.amplitudes.iter().map(|a| a.norm()).collect()
    }

    /// Complex amplitudes a_j as (re, im).
    pub fn complex_amplitudes(&self) -> Vec<(f64, f64)> {
        self.amplitudes.iter().map(|a| (a.re, a.im)).collect()
    }

    /// Mode φ_j (unit 2-norm) as (re, im) per state component.
    pub fn mode(&self, j: usize) -> Option<Vec<(f64, f64)>> {
        (j < self.rank).then(|| (0..self.state_dim()).map(|i| (self.phi_re[(i, j)], self.phi_im[(i, j)])).collect())
    }

    /// Singular values of X (all of them, not only the first r).
    pub fn singular_values(&self) -> &[f64] {
        &self.singular_values
    }

    /// Smallest |f| counted as an oscillation by [`Self::dominant_frequency_hz`]: half a cycle within the
    /// training window, 1 / (2 (m−1) Δt_s). Slower complex pairs are drifts, not oscillations.
    pub fn min_oscillation_frequency_hz(&self) -> f64 {
        1.0 / (2.0 * (self.n_train.max(2) - 1) as f64 * self.dt)
    }

    /// Whether mode j oscillates: at least half a cycle within the training window
    /// (|f| ≥ [`Self::min_oscillation_frequency_hz`]) and not over-damped (|g| ≤ 2π|f|, i.e. it loses less
    /// than a factor e^{2π} per cycle). Excludes the λ ≈ 1 mean-position mode, slow drifts, and the
    /// fast-decaying modes that absorb the noise of x_1 (they can carry large |a_j| without being oscillations).
    pub fn is_oscillating(&self, j: usize) -> bool {
        let Some(w) = self.log_eigenvalues.get(j) else { return false };
        let f = w.im.abs() / (2.0 * std::f64::consts::PI * self.dt);
        let g = w.re / self.dt;
        f >= self.min_oscillation_frequency_hz() * (1.0 - 1e-9) && g.abs() <= 2.0 * std::f64::consts::PI * f
    }

    /// |f| of the largest oscillating mode ([`Self::is_oscillating`]), its size taken as its RMS amplitude over
    /// the training window in the stabilised reconstruction (5.7), |a_j| · sqrt(mean_k |μ_j|^{2k}); `None` if
    /// there is none.
    ///
    /// Not |a_j| alone: the amplitudes are fitted to x_1, so a strongly damped pair that only shapes the first
    /// seconds can carry a large |a_j| (on the 50-s oscillating wall a 0.27 Hz pair decaying at 1.6 s⁻¹ has
    /// |a| = 33 against 3.5 for the 0.49 Hz forced sloshing). Weighting a mode by its time evolution over the
    /// record is the dominant-mode criterion of Kou & Zhang (Eur. J. Mech. B/Fluids 62, 2017).
    pub fn dominant_frequency_hz(&self) -> Option<f64> {
        let f = self.frequencies_hz();
        let size = |j: usize| self.amplitudes[j].norm() * self.window_rms_factor(j);
        // First of the largest (conjugates tie; amplitude order breaks the tie deterministically).
        (0..self.rank)
            .filter(|&j| self.is_oscillating(j))
            .fold(None, |best: Option<usize>, j| match best {
                Some(b) if size(b) >= size(j) => Some(b),
                _ => Some(j),
            })
            .map(|j| f[j].abs())
    }

    /// Per-mode scalars, in amplitude order.
    pub fn modes(&self) -> Vec<ModeSummary> {
        let f = self.frequencies_hz();
        let g = self.growth_rates();
        self.eigenvalues
            .iter()
            .enumerate()
            .map(|(j, l)| ModeSummary {
                index: j,
                eigenvalue: [l.re, l.im],
                abs_eigenvalue: l.norm(),
                frequency_hz: f[j],
                growth_rate: g[j],
                amplitude: self.amplitudes[j].norm(),
                window_rms_amplitude: self.amplitudes[j].norm() * self.window_rms_factor(j),
                oscillating: self.is_oscillating(j),
            })
            .collect()
    }

    /// sqrt((1/m) Σ_{k<m} |μ_j|^{2k}) over the m training snapshots, μ_j the stabilised eigenvalue (|μ_j| = min(|λ_j|, 1)).
    fn window_rms_factor(&self, j: usize) -> f64 {
        let m = self.n_train as f64;
        let q = 2.0 * self.log_eigenvalues[j].re.min(0.0); // ln |μ|², stabilised as in `exponents`
        if q.abs() * m < 1e-9 {
            return 1.0;
        }
        // (1 − |λ|^{2m}) / (m (1 − |λ|²)) written with exp_m1 for accuracy near |λ| = 1.
        ((q * m).exp_m1() / (m * q.exp_m1())).sqrt()
    }

    fn exponents(&self, stabilise: bool) -> Vec<c64> {
        // Stabilisation μ = λ/|λ| for |λ| > 1 (§5.3.1) is Re ln μ = 0.
        self.log_eigenvalues.iter().map(|w| if stabilise && w.re > 0.0 { c64::new(0.0, w.im) } else { *w }).collect()
    }

    /// x̂(t) = Re Σ_j a_j φ_j μ_j^k, k = (t − t_1)/Δt_s (5.7). Any t ≥ t_1 works, including beyond the training
    /// window (prediction); with `stabilise` the unstable eigenvalues are replaced by μ/|μ| (§5.3.1).
    pub fn reconstruct(&self, t_s: f64, stabilise: bool) -> Vec<f64> {
        let x = self.reconstruct_block(&[t_s], &self.exponents(stabilise));
        x.col(0).iter().copied().collect()
    }

    /// (5.7) at several times; one state vector per time.
    pub fn reconstruct_many(&self, times_s: &[f64], stabilise: bool) -> Vec<Vec<f64>> {
        let expo = self.exponents(stabilise);
        let mut out = Vec::with_capacity(times_s.len());
        for chunk in times_s.chunks(RECON_BLOCK) {
            let x = self.reconstruct_block(chunk, &expo);
            out.extend((0..chunk.len()).map(|k| x.col(k).iter().copied().collect::<Vec<f64>>()));
        }
        out
    }

    /// n × times matrix of (5.7): Re(Φ T) = Φ_re Re T − Φ_im Im T with T_jk = a_j exp(k_t ln μ_j).
    fn reconstruct_block(&self, times_s: &[f64], expo: &[c64]) -> Mat<f64> {
        let r = self.rank;
        let nt = times_s.len();
        let mut t_re = Mat::<f64>::zeros(r, nt);
        let mut t_im = Mat::<f64>::zeros(r, nt);
        for (c, &t) in times_s.iter().enumerate() {
            let k = (t - self.t0) / self.dt;
            for j in 0..r {
                let z = if k == 0.0 { c64::new(1.0, 0.0) } else { (expo[j] * k).exp() };
                let v = self.amplitudes[j] * z;
                t_re[(j, c)] = v.re;
                t_im[(j, c)] = v.im;
            }
        }
        let a: Mat<f64> = self.phi_re.as_ref() * t_re.as_ref();
        let b: Mat<f64> = self.phi_im.as_ref() * t_im.as_ref();
        a - b
    }
}

// ---------------------------------------------------------------------------------------------------------------
// Errors of the reconstruction
// ---------------------------------------------------------------------------------------------------------------

fn check_dims(model: &DmdModel, s: &Snapshots) -> Result<(), DmdError> {
    if s.times_s.len() != s.columns.len() {
        return Err(DmdError::TimeCountMismatch { times: s.times_s.len(), columns: s.columns.len() });
    }
    for (k, col) in s.columns.iter().enumerate() {
        if col.len() != model.state_dim() {
            return if k == 0 {
                Err(DmdError::DimensionMismatch { expected: model.state_dim(), got: col.len() })
            } else {
                Err(DmdError::RaggedSnapshot { index: k, len: col.len(), expected: model.state_dim() })
            };
        }
    }
    Ok(())
}

/// Applies `f(k, x̂_k, x_k)` to each snapshot of `s` and its (5.7) reconstruction, blockwise.
fn for_each_reconstruction(
    model: &DmdModel,
    s: &Snapshots,
    stabilise: bool,
    mut f: impl FnMut(usize, &[f64], &[f64]),
) -> Result<(), DmdError> {
    check_dims(model, s)?;
    let expo = model.exponents(stabilise);
    let mut buf = vec![0.0; model.state_dim()];
    for (b, chunk) in s.times_s.chunks(RECON_BLOCK).enumerate() {
        let x = model.reconstruct_block(chunk, &expo);
        for c in 0..chunk.len() {
            let k = b * RECON_BLOCK + c;
            buf.iter_mut().zip(x.col(c).iter()).for_each(|(d, v)| *d = *v);
            f(k, &buf, &s.columns[k]);
        }
    }
    Ok(())
}

/// ‖x̂(t_k) − x_k‖₂ / ‖x_k‖₂ for each snapshot of `s` (absolute error where ‖x_k‖ = 0). `s` may extend beyond
/// the training window (prediction error).
pub fn relative_error_vs_time(model: &DmdModel, s: &Snapshots, stabilise: bool) -> Result<Vec<(f64, f64)>, DmdError> {
    let mut out = Vec::with_capacity(s.len());
    for_each_reconstruction(model, s, stabilise, |k, xr, x| {
        let (mut num, mut den) = (0.0, 0.0);
        for (a, b) in xr.iter().zip(x) {
            num += (a - b) * (a - b);
            den += b * b;
        }
        let e = if den > 0.0 { (num / den).sqrt() } else { num.sqrt() };
        out.push((s.times_s[k], e));
    })?;
    Ok(out)
}

/// Mean over snapshots of [`relative_error_vs_time`].
pub fn reconstruction_error(model: &DmdModel, s: &Snapshots, stabilise: bool) -> Result<f64, DmdError> {
    let e = relative_error_vs_time(model, s, stabilise)?;
    Ok(e.iter().map(|p| p.1).sum::<f64>() / e.len().max(1) as f64)
}

/// Per-time particle position errors (metres).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct PositionError {
    pub t_s: f64,
    /// Mean over particles of |x_rec − x|.
    pub mean_m: f64,
    /// sqrt(mean over particles of |x_rec − x|²) (SPEC §7.13 acceptance metric).
    pub rms_m: f64,
    pub max_m: f64,
}

/// Position errors of the (5.7) reconstruction per snapshot of `s` (which must carry the layout of
/// [`load_frames`] and contain position components).
pub fn position_errors(s: &Snapshots, model: &DmdModel, stabilise: bool) -> Result<Vec<PositionError>, DmdError> {
    let layout = s.layout.as_ref().ok_or(DmdError::NoParticleLayout)?;
    let nc = layout.components.len();
    let pos: Vec<usize> = (0..nc).filter(|&c| layout.components[c].is_position()).collect();
    if pos.is_empty() || layout.particles.len() * nc != s.state_dim() {
        return Err(DmdError::NoParticleLayout);
    }
    let np = layout.particles.len();
    let mut out = Vec::with_capacity(s.len());
    for_each_reconstruction(model, s, stabilise, |k, xr, x| {
        let (mut sum, mut sum2, mut mx) = (0.0, 0.0, 0.0f64);
        for p in 0..np {
            let d2: f64 = pos.iter().map(|&c| (xr[p * nc + c] - x[p * nc + c]).powi(2)).sum();
            let d = d2.sqrt();
            sum += d;
            sum2 += d2;
            mx = mx.max(d);
        }
        out.push(PositionError {
            t_s: s.times_s[k],
            mean_m: sum / np as f64,
            rms_m: (sum2 / np as f64).sqrt(),
            max_m: mx,
        });
    })?;
    Ok(out)
}

/// Per snapshot: mean over particles of |x_rec − x| in metres (for the §7.13 check "< 5 % of the tank width").
pub fn mean_position_error(s: &Snapshots, model: &DmdModel, stabilise: bool) -> Result<Vec<f64>, DmdError> {
    Ok(position_errors(s, model, stabilise)?.into_iter().map(|e| e.mean_m).collect())
}

/// Reduced-order models (§5.3.1, SPEC §8.3): for each requested rank (clamped to the numerical rank; duplicates
/// after clamping removed), the mean relative reconstruction error of the stabilised model over `s`.
/// Returns (rank used, error). The SVD is computed once.
pub fn rom_error_vs_rank(s: &Snapshots, ranks: &[usize]) -> Result<Vec<(usize, f64)>, DmdError> {
    rom_error_vs_rank_with(s, ranks, AmplitudeFit::InitialCondition)
}

/// [`rom_error_vs_rank`] with a choice of amplitude fit.
pub fn rom_error_vs_rank_with(
    s: &Snapshots,
    ranks: &[usize],
    amplitudes: AmplitudeFit,
) -> Result<Vec<(usize, f64)>, DmdError> {
    let d = Decomposition::new(s)?;
    rom_error_with(&d, s, ranks, amplitudes)
}

fn rom_error_with(
    d: &Decomposition,
    s: &Snapshots,
    ranks: &[usize],
    amplitudes: AmplitudeFit,
) -> Result<Vec<(usize, f64)>, DmdError> {
    let mut out: Vec<(usize, f64)> = Vec::with_capacity(ranks.len());
    for &r in ranks {
        let ru = d.select_rank(RankSelection::Rank(r))?;
        if out.iter().any(|(q, _)| *q == ru) {
            continue;
        }
        let model = d.model_at_rank(ru, RankSelection::Rank(r), amplitudes)?;
        out.push((ru, reconstruction_error(&model, s, true)?));
    }
    Ok(out)
}

/// Default ranks for the ROM sweep: 1, 2, 4, 8, … below the numerical rank, then the model's and the numerical rank.
pub fn default_rom_ranks(numerical_rank: usize, model_rank: usize) -> Vec<usize> {
    let mut v: Vec<usize> =
        std::iter::successors(Some(1usize), |r| r.checked_mul(2)).take_while(|&r| r < numerical_rank).collect();
    v.push(model_rank.min(numerical_rank).max(1));
    v.push(numerical_rank.max(1));
    v.sort_unstable();
    v.dedup();
    v
}

// ---------------------------------------------------------------------------------------------------------------
// Report and plots
// ---------------------------------------------------------------------------------------------------------------

/// Contents of `dmd.json`.
#[derive(Clone, Debug, Serialize)]
pub struct DmdReport {
    /// "rank R", "energy E" or "full (numerical rank)".
    pub selection: String,
    /// How the amplitudes were fitted ("initial condition x_1" = thesis).
    pub amplitude_fit: String,
    /// Rank r used.
    pub rank: usize,
    pub numerical_rank: usize,
    pub state_dim: usize,
    pub n_snapshots: usize,
    pub dt_s: f64,
    pub t0_s: f64,
    pub layout: Option<StateLayout>,
    /// λ_j as [re, im], modes ordered by amplitude.
    pub eigenvalues: Vec<[f64; 2]>,
    /// μ_j after the §5.3.1 projection of |λ| > 1 onto the unit circle.
    pub stabilised_eigenvalues: Vec<[f64; 2]>,
    pub n_unstable: usize,
    pub amplitudes: Vec<f64>,
    pub frequencies_hz: Vec<f64>,
    /// 1/s.
    pub growth_rates: Vec<f64>,
    pub dominant_frequency_hz: Option<f64>,
    pub min_oscillation_frequency_hz: f64,
    pub singular_values: Vec<f64>,
    pub cumulative_energy: Vec<f64>,
    /// E(r) at the rank used.
    pub energy_at_rank: f64,
    /// Mean relative error ‖x̂_k − x_k‖/‖x_k‖ of the stabilised reconstruction over the snapshots.
    pub reconstruction_error: f64,
    /// Same without stabilisation (null when it overflows).
    pub reconstruction_error_unstabilised: f64,
    /// [t, relative error] of the stabilised reconstruction.
    pub reconstruction_error_vs_time: Vec<[f64; 2]>,
    /// Per-time particle position errors (when the snapshots come from frames with positions).
    pub position_error_vs_time: Option<Vec<PositionError>>,
    pub max_mean_position_error_m: Option<f64>,
    pub max_rms_position_error_m: Option<f64>,
    /// [rank, mean relative error of the stabilised truncated model].
    pub rom_error_vs_rank: Vec<(usize, f64)>,
    /// The ten largest-amplitude modes.
    pub top_modes: Vec<ModeSummary>,
    /// Files written (names relative to the output directory).
    pub files: Vec<String>,
}

/// Writes eigenvalues.png, frequency_amplitude.png, growth_rate_amplitude.png, cumulative_energy.png,
/// reconstruction_error.png, rom_error_vs_rank.png (and position_error.png with a particle layout) plus dmd.json.
/// `model` must have been fitted on `s`. Recomputes the SVD of X for the ROM sweep; use [`write_outputs_with`]
/// to reuse a [`Decomposition`].
pub fn write_outputs(model: &DmdModel, s: &Snapshots, out_dir: &Path) -> Result<DmdReport, DmdError> {
    let d = Decomposition::new(s)?;
    let ranks = default_rom_ranks(d.numerical_rank(), model.rank());
    write_outputs_with(&d, model, s, out_dir, &ranks)
}

/// [`write_outputs`] with a precomputed decomposition of `s` and an explicit ROM rank list.
pub fn write_outputs_with(
    d: &Decomposition,
    model: &DmdModel,
    s: &Snapshots,
    out_dir: &Path,
    rom_ranks: &[usize],
) -> Result<DmdReport, DmdError> {
    std::fs::create_dir_all(out_dir).map_err(io_err(out_dir))?;
    let err_t = relative_error_vs_time(model, s, true)?;
    let err_t_raw = relative_error_vs_time(model, s, false)?;
    let mean = |v: &[(f64, f64)]| v.iter().map(|p| p.1).sum::<f64>() / v.len().max(1) as f64;
    let pos_err = match position_errors(s, model, true) {
        Ok(p) => Some(p),
        Err(DmdError::NoParticleLayout) => None,
        Err(e) => return Err(e),
    };
    let rom = rom_error_with(d, s, rom_ranks, model.amplitude_fit())?;
    let cum = cumulative_energy(model.singular_values());
    let freqs = model.frequencies_hz();
    let growth = model.growth_rates();
    let amps = model.amplitudes();
    let eig = model.eigenvalues();
    let dominant = model.dominant_frequency_hz();
    let mut files = Vec::new();

    // Eigenvalues and the unit circle (Figs. 5.3, 5.10, 5.13): red = |λ| > 1.
    let circle: Vec<(f64, f64)> = (0..=360).map(|k| (k as f64).to_radians()).map(|a| (a.cos(), a.sin())).collect();
    let stable: Vec<(f64, f64)> = eig.iter().copied().filter(|(a, b)| a.hypot(*b) <= 1.0).collect();
    let unstable: Vec<(f64, f64)> = eig.iter().copied().filter(|(a, b)| a.hypot(*b) > 1.0).collect();
    let rmax = eig.iter().map(|(a, b)| a.hypot(*b)).filter(|v| v.is_finite()).fold(1.0, f64::max) * 1.08;
    let title = format!("DMD eigenvalues (r = {}, {} with |λ|>1)", model.rank(), unstable.len());
    draw_chart(
        &out_dir.join("eigenvalues.png"),
        &ChartSpec {
            title: &title,
            x_label: "Re λ",
            y_label: "Im λ",
            square: true,
            x_range: Some((-rmax, rmax)),
            y_range: Some((-rmax, rmax)),
            legend: SeriesLabelPosition::UpperLeft,
            series: vec![
                PlotSeries::line("unit circle", circle, BLACK),
                PlotSeries::markers("|λ| ≤ 1", stable, BLUE_C),
                PlotSeries::markers("|λ| > 1 (→ λ/|λ|)", unstable, RED_C),
            ],
        },
    )?;
    files.push("eigenvalues.png".to_string());

    // Frequency and growth rate against amplitude (Figs. 5.4, 5.5).
    let log_amp: Vec<f64> = amps.iter().map(|a| a.log10()).collect();
    let mut fa =
        vec![PlotSeries::markers("modes", freqs.iter().copied().zip(log_amp.iter().copied()).collect(), BLUE_C)];
    if let Some(fd) = dominant
        && let Some(j) = freqs.iter().position(|f| (f.abs() - fd).abs() <= 1e-12 * fd.max(1.0))
    {
        fa.push(PlotSeries::markers(&format!("dominant {fd:.4} Hz"), vec![(freqs[j], log_amp[j])], RED_C));
    }
    draw_chart(
        &out_dir.join("frequency_amplitude.png"),
        &ChartSpec {
            title: "DMD mode frequency vs amplitude",
            x_label: "frequency f = Im(ln λ)/(2π Δt) [Hz]",
            y_label: "log10 |a|",
            square: false,
            x_range: None,
            y_range: None,
            legend: LEGEND_POS,
            series: fa,
        },
    )?;
    files.push("frequency_amplitude.png".to_string());
    draw_chart(
        &out_dir.join("growth_rate_amplitude.png"),
        &ChartSpec {
            title: "DMD mode growth rate vs amplitude",
            x_label: "growth rate g = Re(ln λ)/Δt [1/s]",
            y_label: "log10 |a|",
            square: false,
            x_range: None,
            y_range: None,
            legend: LEGEND_POS,
            series: vec![PlotSeries::markers(
                "modes",
                growth.iter().copied().zip(log_amp.iter().copied()).collect(),
                BLUE_C,
            )],
        },
    )?;
    files.push("growth_rate_amplitude.png".to_string());

    // Cumulative singular-value energy (Fig. 5.9).
    let cum_pts: Vec<(f64, f64)> = cum.iter().enumerate().map(|(k, e)| ((k + 1) as f64, *e)).collect();
    let e_r = cum.get(model.rank().saturating_sub(1)).copied().unwrap_or(0.0);
    draw_chart(
        &out_dir.join("cumulative_energy.png"),
        &ChartSpec {
            title: "Cumulative energy of the singular values of X",
            x_label: "number of modes r",
            y_label: "E(r) = Σσ_k² (k≤r) / Σσ_k²",
            square: false,
            x_range: None,
            y_range: None,
            legend: SeriesLabelPosition::LowerRight,
            series: vec![
                PlotSeries::line("E(r)", cum_pts, BLUE_C),
                PlotSeries::markers(
                    &format!("r = {} (E = {:.4})", model.rank(), e_r),
                    vec![(model.rank() as f64, e_r)],
                    RED_C,
                ),
            ],
        },
    )?;
    files.push("cumulative_energy.png".to_string());

    // Reconstruction error against time (5.7).
    let lg = |v: &[(f64, f64)]| -> Vec<(f64, f64)> { v.iter().map(|(t, e)| (*t, e.log10())).collect() };
    draw_chart(
        &out_dir.join("reconstruction_error.png"),
        &ChartSpec {
            title: "DMD reconstruction error (5.7)",
            x_label: "t [s]",
            y_label: "log10 ‖x_rec − x‖ / ‖x‖",
            square: false,
            x_range: None,
            y_range: None,
            legend: LEGEND_POS,
            series: vec![
                PlotSeries::line("stabilised (μ/|μ|)", lg(&err_t), BLUE_C),
                PlotSeries::line("unstabilised", lg(&err_t_raw), RED_C),
            ],
        },
    )?;
    files.push("reconstruction_error.png".to_string());

    if let Some(pe) = &pos_err {
        draw_chart(
            &out_dir.join("position_error.png"),
            &ChartSpec {
                title: "Particle position error of the stabilised reconstruction",
                x_label: "t [s]",
                y_label: "error [m]",
                square: false,
                x_range: None,
                y_range: None,
                legend: LEGEND_POS,
                series: vec![
                    PlotSeries::line("mean", pe.iter().map(|e| (e.t_s, e.mean_m)).collect(), BLUE_C),
                    PlotSeries::line("rms", pe.iter().map(|e| (e.t_s, e.rms_m)).collect(), GREEN_C),
                ],
            },
        )?;
        files.push("position_error.png".to_string());
    }

    // Reduced-order model error against rank (§5.3.1, SPEC §8.3).
    let rom_pts: Vec<(f64, f64)> = rom.iter().map(|(r, e)| (*r as f64, e.log10())).collect();
    draw_chart(
        &out_dir.join("rom_error_vs_rank.png"),
        &ChartSpec {
            title: "Truncated DMD model: error vs rank",
            x_label: "rank r",
            y_label: "log10 mean ‖x_rec − x‖ / ‖x‖",
            square: false,
            x_range: None,
            y_range: None,
            legend: LEGEND_POS,
            series: vec![
                PlotSeries::line("stabilised", rom_pts.clone(), BLUE_C),
                PlotSeries::markers("", rom_pts, BLUE_C),
            ],
        },
    )?;
    files.push("rom_error_vs_rank.png".to_string());
    files.push("dmd.json".to_string());

    let max_of = |it: &mut dyn Iterator<Item = f64>| it.fold(0.0, f64::max);
    let report = DmdReport {
        selection: model.selection().to_string(),
        amplitude_fit: model.amplitude_fit().to_string(),
        rank: model.rank(),
        numerical_rank: model.numerical_rank(),
        state_dim: model.state_dim(),
        n_snapshots: s.len(),
        dt_s: model.dt(),
        t0_s: model.t0(),
        layout: s.layout.clone(),
        eigenvalues: eig.iter().map(|(a, b)| [*a, *b]).collect(),
        stabilised_eigenvalues: model.stabilised_eigenvalues().iter().map(|(a, b)| [*a, *b]).collect(),
        n_unstable: model.n_unstable(),
        amplitudes: amps,
        frequencies_hz: freqs,
        growth_rates: growth,
        dominant_frequency_hz: dominant,
        min_oscillation_frequency_hz: model.min_oscillation_frequency_hz(),
        singular_values: model.singular_values().to_vec(),
        cumulative_energy: cum,
        energy_at_rank: e_r,
        reconstruction_error: mean(&err_t),
        reconstruction_error_unstabilised: mean(&err_t_raw),
        reconstruction_error_vs_time: err_t.iter().map(|(t, e)| [*t, *e]).collect(),
        max_mean_position_error_m: pos_err.as_ref().map(|p| max_of(&mut p.iter().map(|e| e.mean_m))),
        max_rms_position_error_m: pos_err.as_ref().map(|p| max_of(&mut p.iter().map(|e| e.rms_m))),
        position_error_vs_time: pos_err,
        rom_error_vs_rank: rom,
        top_modes: model.modes().into_iter().take(10).collect(),
        files,
    };
    let path = out_dir.join("dmd.json");
    let text = serde_json::to_string_pretty(&report).map_err(|source| DmdError::Json { path: path.clone(), source })?;
    std::fs::write(&path, text).map_err(io_err(&path))?;
    Ok(report)
}

/// `perfuse dmd FRAMES_DIR [--rank R | --energy E] [--out DIR]`: load, fit, write. The frame interval is not in
/// the frame files; the caller passes the run's `output.frame_interval`.
pub fn run_dmd(
    frames_dir: &Path,
    frame_interval_s: f64,
    fields: FrameFields,
    sel: RankSelection,
    amplitudes: AmplitudeFit,
    out_dir: &Path,
) -> Result<DmdReport, DmdError> {
    let s = load_frames(frames_dir, frame_interval_s, fields)?;
    let d = Decomposition::new(&s)?;
    let model = d.model_with(sel, amplitudes)?;
    let ranks = default_rom_ranks(d.numerical_rank(), model.rank());
    write_outputs_with(&d, &model, &s, out_dir, &ranks)
}

const LEGEND_POS: SeriesLabelPosition = SeriesLabelPosition::UpperRight;
const BLUE_C: RGBColor = RGBColor(30, 90, 200);
const RED_C: RGBColor = RGBColor(200, 30, 30);
const GREEN_C: RGBColor = RGBColor(30, 150, 60);

struct PlotSeries {
    label: String,
    points: Vec<(f64, f64)>,
    colour: RGBColor,
    markers: bool,
}

impl PlotSeries {
    fn line(label: &str, points: Vec<(f64, f64)>, colour: RGBColor) -> Self {
        PlotSeries { label: label.into(), points, colour, markers: false }
    }
    fn markers(label: &str, points: Vec<(f64, f64)>, colour: RGBColor) -> Self {
        PlotSeries { label: label.into(), points, colour, markers: true }
    }
}

struct ChartSpec<'a> {
    title: &'a str,
    x_label: &'a str,
    y_label: &'a str,
    /// Square canvas with equal label areas (the eigenvalue plane).
    square: bool,
    x_range: Option<(f64, f64)>,
    y_range: Option<(f64, f64)>,
    legend: SeriesLabelPosition,
    series: Vec<PlotSeries>,
}

fn finite_range(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in vals.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !(lo.is_finite() && hi.is_finite()) {
        return (0.0, 1.0);
    }
    let span = hi - lo;
    if span <= 1e-12 * lo.abs().max(hi.abs()).max(1e-300) {
        let d = (0.5 * lo.abs()).max(0.5);
        return (lo - d, hi + d);
    }
    (lo - 0.05 * span, hi + 0.05 * span)
}

/// Renders a chart to PNG (plotters on an RGB buffer, saved with `image`, as analysis/plot.rs).
fn draw_chart(path: &Path, spec: &ChartSpec) -> Result<(), DmdError> {
    FONT_ONCE.call_once(|| {
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
    let perr = |e: &dyn fmt::Display| DmdError::Plot { path: path.to_path_buf(), message: e.to_string() };
    let (w, h) = if spec.square { (760u32, 760u32) } else { (900u32, 600u32) };
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| perr(&e))?;
        let all = || spec.series.iter().flat_map(|s| s.points.iter()).filter(|p| p.0.is_finite() && p.1.is_finite());
        let (x0, x1) = spec.x_range.unwrap_or_else(|| finite_range(all().map(|p| p.0)));
        let (y0, y1) = spec.y_range.unwrap_or_else(|| finite_range(all().map(|p| p.1)));
        let (xa, ya) = if spec.square { (60, 60) } else { (45, 80) };
        let mut cc = ChartBuilder::on(&root)
            .caption(spec.title, ("sans-serif", 22))
            .margin(15)
            .x_label_area_size(xa)
            .y_label_area_size(ya)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| perr(&e))?;
        cc.configure_mesh()
            .x_desc(spec.x_label)
            .y_desc(spec.y_label)
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(|e| perr(&e))?;
        let inside = |p: &(f64, f64)| p.0.is_finite() && p.1.is_finite();
        for s in &spec.series {
            let col = s.colour;
            let pts: Vec<(f64, f64)> = s.points.iter().copied().filter(inside).collect();
            if s.markers {
                let drawn =
                    cc.draw_series(pts.iter().map(|&p| Circle::new(p, 3, col.filled()))).map_err(|e| perr(&e))?;
                if !s.label.is_empty() {
                    drawn.label(s.label.clone()).legend(move |(x, y)| Circle::new((x + 10, y), 3, col.filled()));
                }
            } else {
                let drawn = cc.draw_series(LineSeries::new(pts, col.stroke_width(2))).map_err(|e| perr(&e))?;
                if !s.label.is_empty() {
                    drawn
                        .label(s.label.clone())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2)));
                }
            }
        }
        cc.configure_series_labels()
            .position(spec.legend.clone())
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .draw()
            .map_err(|e| perr(&e))?;
        root.present().map_err(|e| perr(&e))?;
    }
    image::save_buffer(path, &buf, w, h, image::ColorType::Rgb8).map_err(|e| perr(&e))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_dir::TmpDir;
    use std::f64::consts::PI;

    /// SplitMix64 + Box–Muller (no rand dependency).
    struct Rng(u64);
    impl Rng {
        fn uniform(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }
        fn normal(&mut self) -> f64 {
            let (u1, u2) = (self.uniform(), self.uniform());
            (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
        }
    }

    /// n × d matrix with orthonormal columns (thin Q of a Gaussian matrix).
    fn orthonormal(n: usize, d: usize, rng: &mut Rng) -> Mat<f64> {
        let g = Mat::<f64>::from_fn(n, d, |_, _| rng.normal());
        g.qr().compute_thin_Q()
    }

    /// Block-diagonal real operator: 2×2 rotation–scaling blocks for complex pairs ρe^{±iθ}, 1×1 for reals.
    enum Eig {
        Pair(f64, f64),
        Real(f64),
    }

    fn block_operator(eigs: &[Eig]) -> (Mat<f64>, Vec<c64>) {
        let d: usize = eigs.iter().map(|e| if matches!(e, Eig::Pair(..)) { 2 } else { 1 }).sum();
        let mut a = Mat::<f64>::zeros(d, d);
        let mut expected = Vec::new();
        let mut k = 0;
        for e in eigs {
            match *e {
                Eig::Pair(rho, th) => {
                    a[(k, k)] = rho * th.cos();
                    a[(k, k + 1)] = -rho * th.sin();
                    a[(k + 1, k)] = rho * th.sin();
                    a[(k + 1, k + 1)] = rho * th.cos();
                    expected.push(c64::new(rho * th.cos(), rho * th.sin()));
                    expected.push(c64::new(rho * th.cos(), -rho * th.sin()));
                    k += 2;
                }
                Eig::Real(l) => {
                    a[(k, k)] = l;
                    expected.push(c64::new(l, 0.0));
                    k += 1;
                }
            }
        }
        (a, expected)
    }

    /// x_{k+1} = A x_k with A = Q A_b Qᵀ, Q an n × d orthonormal lift of the block operator; z_0 given.
    fn lifted_system(n: usize, eigs: &[Eig], z0: &[f64], m: usize, dt: f64, seed: u64) -> (Snapshots, Vec<c64>) {
        let mut rng = Rng(seed);
        let (a, expected) = block_operator(eigs);
        let d = a.nrows();
        let q = orthonormal(n, d, &mut rng);
        let mut z = Mat::<f64>::from_fn(d, 1, |i, _| z0[i]);
        let mut cols = Vec::with_capacity(m);
        for _ in 0..m {
            let x: Mat<f64> = q.as_ref() * z.as_ref();
            cols.push(x.col(0).iter().copied().collect());
            z = a.as_ref() * z.as_ref();
        }
        (Snapshots::uniform(dt, cols), expected)
    }

    /// Max over expected eigenvalues of the distance to the nearest recovered one (and 1-to-1 check).
    fn eig_match(model: &DmdModel, expected: &[c64]) -> f64 {
        let got: Vec<c64> = model.eigenvalues().iter().map(|(a, b)| c64::new(*a, *b)).collect();
        assert_eq!(got.len(), expected.len(), "rank {} vs {} expected eigenvalues", got.len(), expected.len());
        let mut used = vec![false; got.len()];
        let mut worst = 0.0f64;
        for e in expected {
            let (j, d) = got
                .iter()
                .enumerate()
                .filter(|(j, _)| !used[*j])
                .map(|(j, g)| (j, (g - e).norm()))
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .expect("an unused eigenvalue");
            used[j] = true;
            worst = worst.max(d);
        }
        worst
    }

    fn norm(v: &[f64]) -> f64 {
        v.iter().map(|x| x * x).sum::<f64>().sqrt()
    }

    /// A fresh temporary directory for one test (removed when it ends).
    fn temp_dir(name: &str) -> TmpDir {
        TmpDir::new(&format!("perfuse_dmd_test_{name}"))
    }

    // --- 1. synthetic linear system ------------------------------------------------------------------------

    #[test]
    fn recovers_known_eigenvalues_of_lifted_linear_system() {
        let eigs = [Eig::Pair(0.99, 0.3), Eig::Pair(0.95, 1.1), Eig::Real(0.9)];
        let (s, expected) = lifted_system(50, &eigs, &[1.0, 0.5, 0.8, -0.6, 1.2], 100, 0.1, 7);
        let model = fit(&s, RankSelection::Full).expect("fit");
        assert_eq!(model.rank(), 5);
        let err = eig_match(&model, &expected);
        eprintln!("lifted system: max eigenvalue error {err:.2e}");
        assert!(err < 1e-6, "eigenvalue error {err:e}");
        // Frequencies and growth rates of the pair 0.99e^{±0.3i}: ±0.3/(2π·0.1) Hz, ln(0.99)/0.1 1/s.
        let f = model.frequencies_hz();
        let g = model.growth_rates();
        let j = f.iter().position(|v| (v - 0.3 / (2.0 * PI * 0.1)).abs() < 1e-6).expect("0.3 rad/step mode");
        assert!((g[j] - 0.99f64.ln() / 0.1).abs() < 1e-6);
        // Reconstruction of the training snapshots (5.7).
        let e = reconstruction_error(&model, &s, false).expect("error");
        assert!(e < 1e-8, "reconstruction error {e:e}");
    }

    /// SPEC §8.5 (D1): n = 64, (g, f) ∈ {(0, 0.5), (−0.1, 1.3), (−0.5, 2.1)}, m = 200, Δt_s = 0.01 s.
    #[test]
    fn spec_d1_synthetic_case() {
        let dt = 0.01;
        let gf = [(0.0, 0.5), (-0.1, 1.3), (-0.5, 2.1)];
        let eigs: Vec<Eig> =
            gf.iter().map(|&(g, f): &(f64, f64)| Eig::Pair((g * dt).exp(), 2.0 * PI * f * dt)).collect();
        let (s, expected) = lifted_system(64, &eigs, &[1.0, 0.3, -0.7, 0.9, 0.4, 1.1], 200, dt, 11);
        let model = fit(&s, RankSelection::Full).expect("fit");
        assert_eq!(model.rank(), 6);
        let err = eig_match(&model, &expected);
        eprintln!("D1: max eigenvalue error {err:.2e}");
        assert!(err < 1e-8);
        let f = model.frequencies_hz();
        let g = model.growth_rates();
        for &(g0, f0) in &gf {
            let j = f.iter().position(|v| (v - f0).abs() < 1e-6).expect("frequency recovered");
            assert!((g[j] - g0).abs() < 1e-6, "growth {} vs {g0}", g[j]);
            assert!(f.iter().any(|v| (v + f0).abs() < 1e-6), "conjugate −f");
        }
        let e = reconstruction_error(&model, &s, true).expect("error");
        eprintln!("D1: mean relative reconstruction error {e:.2e}");
        assert!(e < 1e-8, "reconstruction error {e:e}");
        assert_eq!(model.dominant_frequency_hz().map(|v| v > 0.0), Some(true));
    }

    #[test]
    fn predicts_beyond_the_training_window() {
        let eigs = [Eig::Pair(0.995, 0.2), Eig::Pair(0.97, 0.9), Eig::Real(0.93)];
        let (s, _) = lifted_system(30, &eigs, &[1.0, 0.0, 0.5, 0.5, 1.0], 160, 0.05, 3);
        let train = s.slice(0..60);
        let test = s.slice(60..160);
        let model = fit(&train, RankSelection::Full).expect("fit");
        let e = relative_error_vs_time(&model, &test, true).expect("prediction error");
        let worst = e.iter().map(|p| p.1).fold(0.0, f64::max);
        eprintln!("prediction over 100 steps past a 60-snapshot window: max relative error {worst:.2e}");
        assert!(worst < 1e-7, "prediction error {worst:e}");
        // Single-time API, 100 steps past the window.
        let x = model.reconstruct(test.times_s[99], true);
        let d: Vec<f64> = x.iter().zip(&test.columns[99]).map(|(a, b)| a - b).collect();
        assert!(norm(&d) < 1e-7 * norm(&test.columns[99]));
    }

    #[test]
    fn all_snapshot_amplitudes_minimise_the_window_error() {
        // Exact linear data: both fits reproduce the record.
        let eigs = [Eig::Pair(0.99, 0.3), Eig::Pair(0.95, 1.1), Eig::Real(0.9)];
        let (s, _) = lifted_system(30, &eigs, &[1.0, 0.5, 0.8, -0.6, 1.2], 80, 0.1, 17);
        let m = fit_with(&s, RankSelection::Full, AmplitudeFit::AllSnapshots).expect("fit");
        assert_eq!(m.amplitude_fit(), AmplitudeFit::AllSnapshots);
        assert!(reconstruction_error(&m, &s, true).expect("e") < 1e-8);
        for j in 0..m.rank() {
            let phi = m.mode(j).expect("mode");
            let nrm: f64 = phi.iter().map(|(a, b)| a * a + b * b).sum::<f64>().sqrt();
            assert!((nrm - 1.0).abs() < 1e-12);
        }
        assert!(m.mode(m.rank()).is_none());
        // Nonlinear record (x_k = c + u sin(ωt)² + v t e^{−t} + noise), truncated model: the all-snapshot fit
        // has the smallest summed squared error of the stabilised reconstruction.
        let mut rng = Rng(3);
        let n = 25;
        let basis = orthonormal(n, 4, &mut rng);
        let cols: Vec<Vec<f64>> = (0..120)
            .map(|k| {
                let t = k as f64 * 0.05;
                let c = [2.0, (1.3 * t).sin().powi(2), t * (-t).exp(), (0.7 * t).cos().powi(3)];
                (0..n).map(|i| (0..4).map(|j| basis[(i, j)] * c[j]).sum::<f64>() + 1e-3 * rng.normal()).collect()
            })
            .collect();
        let s = Snapshots::uniform(0.05, cols);
        let sse = |m: &DmdModel| -> f64 {
            let mut acc = 0.0;
            for_each_reconstruction(m, &s, true, |_, xr, x| {
                acc += xr.iter().zip(x).map(|(a, b)| (a - b) * (a - b)).sum::<f64>();
            })
            .expect("sse");
            acc
        };
        let m_ic = fit(&s, RankSelection::Rank(6)).expect("ic");
        let m_all = fit_with(&s, RankSelection::Rank(6), AmplitudeFit::AllSnapshots).expect("all");
        let (e_ic, e_all) = (sse(&m_ic), sse(&m_all));
        assert!(e_all <= e_ic * (1.0 + 1e-9), "all-snapshot SSE {e_all} > initial-condition SSE {e_ic}");
        // refit_amplitudes on the initial-condition model gives the same optimum.
        let mut m_re = m_ic.clone();
        m_re.refit_amplitudes(&s, true).expect("refit");
        assert!((sse(&m_re) - e_all).abs() <= 1e-8 * e_all.max(1e-30));
    }

    // --- 2. sinusoid ------------------------------------------------------------------------------------------

    #[test]
    fn sinusoid_frequency_and_dominant_mode() {
        let mut rng = Rng(5);
        let n = 12;
        let q = orthonormal(n, 5, &mut rng);
        let dt = 0.01;
        let cols: Vec<Vec<f64>> = (0..301)
            .map(|k| {
                let t = k as f64 * dt;
                let w1 = 2.0 * PI * 0.5 * t;
                let w2 = 2.0 * PI * 1.7 * t;
                // Large constant offset (mean position, λ = 1), 0.5 Hz at amplitude 1, 1.7 Hz at 0.3.
                let c = [5.0, w1.sin(), w1.cos(), 0.3 * w2.sin(), 0.3 * w2.cos()];
                (0..n).map(|i| (0..5).map(|j| q[(i, j)] * c[j]).sum()).collect()
            })
            .collect();
        let s = Snapshots::uniform(dt, cols);
        let model = fit(&s, RankSelection::Full).expect("fit");
        assert_eq!(model.rank(), 5);
        let f = model.frequencies_hz();
        for f0 in [0.5, -0.5, 1.7, -1.7, 0.0] {
            assert!(f.iter().any(|v| (v - f0).abs() < 1e-8), "frequency {f0} not in {f:?}");
        }
        // The largest mode is the mean (λ = 1, f = 0); dominant_frequency_hz skips it.
        assert!(f[0].abs() < 1e-9);
        let (l0r, l0i) = model.eigenvalues()[0];
        assert!((l0r - 1.0).abs() < 1e-9 && l0i.abs() < 1e-9);
        let fd = model.dominant_frequency_hz().expect("an oscillating mode");
        assert!((fd - 0.5).abs() < 1e-8, "dominant {fd}");
        assert!(model.growth_rates().iter().all(|g| g.abs() < 1e-6));
    }

    #[test]
    fn dominant_frequency_ignores_fast_transients() {
        // Mean mode (λ = 1), a persistent pair e^{±0.2i} of amplitude 1, and a transient pair 0.3e^{±0.5i} of
        // amplitude 5 that is gone after a few snapshots.
        let eigs = [Eig::Real(1.0), Eig::Pair(1.0, 0.2), Eig::Pair(0.3, 0.5)];
        let (s, _) = lifted_system(20, &eigs, &[3.0, 1.0, 0.0, 5.0, 0.0], 200, 0.1, 23);
        let model = fit(&s, RankSelection::Full).expect("fit");
        let modes = model.modes();
        let top_transient = modes.iter().position(|md| md.growth_rate < -1.0).expect("transient");
        let top_persistent = modes.iter().position(|md| md.oscillating).expect("oscillation");
        assert!(top_transient < top_persistent, "the transient should have the larger |a|: {modes:?}");
        assert!(modes[top_transient].window_rms_amplitude < modes[top_persistent].window_rms_amplitude);
        let fd = model.dominant_frequency_hz().expect("dominant");
        assert!((fd - 0.2 / (2.0 * PI * 0.1)).abs() < 1e-8, "dominant {fd}");
    }

    #[test]
    fn dominant_frequency_weighs_damped_pairs_by_their_life_in_the_window() {
        // A damped pair 0.9e^{±0.5i} (g = −1.05 s⁻¹, f = 0.80 Hz: under a factor e^{2π} per cycle, so it counts as
        // an oscillation) with five times the amplitude of the persistent pair e^{±0.2i}: over 200 snapshots
        // its RMS size is 5 · 0.16 = 0.8 against 1, so the persistent pair is the dominant one.
        let eigs = [Eig::Real(1.0), Eig::Pair(1.0, 0.2), Eig::Pair(0.9, 0.5)];
        let (s, _) = lifted_system(20, &eigs, &[3.0, 1.0, 0.0, 5.0, 0.0], 200, 0.1, 29);
        let model = fit(&s, RankSelection::Full).expect("fit");
        let modes = model.modes();
        let damped = modes.iter().position(|md| md.growth_rate < -0.5).expect("damped pair");
        let persistent = modes.iter().position(|md| md.oscillating && md.growth_rate.abs() < 1e-6).expect("pair");
        assert!(modes[damped].oscillating, "the damped pair is an oscillation: {:?}", modes[damped]);
        assert!(damped < persistent, "the damped pair should have the larger |a|: {modes:?}");
        assert!(modes[damped].window_rms_amplitude < modes[persistent].window_rms_amplitude);
        let fd = model.dominant_frequency_hz().expect("dominant");
        assert!((fd - 0.2 / (2.0 * PI * 0.1)).abs() < 1e-8, "dominant {fd}");
    }

    // --- 3. stabilisation -------------------------------------------------------------------------------------

    #[test]
    fn stabilisation_bounds_the_forecast() {
        let eigs = [Eig::Pair(1.01, 0.2), Eig::Pair(0.97, 0.7), Eig::Real(0.9)];
        let (s, expected) = lifted_system(40, &eigs, &[1.0, 0.2, 0.7, -0.4, 0.9], 100, 0.01, 9);
        let model = fit(&s, RankSelection::Full).expect("fit");
        assert!(eig_match(&model, &expected) < 1e-8);
        assert_eq!(model.n_unstable(), 2);
        assert!(model.stabilised_eigenvalues().iter().all(|(a, b)| a.hypot(*b) <= 1.0 + 1e-12));
        let xmax = s.columns.iter().map(|c| norm(c)).fold(0.0, f64::max);
        let t_far = s.times_s[0] + 10_000.0 * model.dt();
        let stab = model.reconstruct(t_far, true);
        assert!(stab.iter().all(|v| v.is_finite()));
        assert!(norm(&stab) <= 2.0 * xmax, "stabilised {} vs 2 max ‖x‖ = {}", norm(&stab), 2.0 * xmax);
        let raw = model.reconstruct(t_far, false);
        eprintln!(
            "stabilisation: ‖x(10 000 steps)‖ = {:.3e} stabilised, {:.3e} unstabilised, max ‖x_k‖ = {xmax:.3e}",
            norm(&stab),
            norm(&raw)
        );
        assert!(norm(&raw) > 1e30, "unstabilised forecast should blow up, got {}", norm(&raw));
        // Bounded over the whole 10 000-step forecast.
        let times: Vec<f64> = (0..=10_000).step_by(50).map(|k| s.times_s[0] + k as f64 * model.dt()).collect();
        for x in model.reconstruct_many(&times, true) {
            assert!(norm(&x) <= 2.0 * xmax);
        }
    }

    // --- 4. energy selection and reduced-order models ---------------------------------------------------------

    #[test]
    fn energy_selection_picks_expected_rank() {
        let mut rng = Rng(21);
        let (n, m) = (20, 31);
        let sig = [10.0, 5.0, 1.0, 0.1, 0.01];
        let u = orthonormal(n, 5, &mut rng);
        let v = orthonormal(m - 1, 5, &mut rng);
        let cols: Vec<Vec<f64>> = (0..m)
            .map(|k| {
                let kk = k.min(m - 2);
                (0..n).map(|i| (0..5).map(|j| u[(i, j)] * sig[j] * v[(kk, j)]).sum()).collect()
            })
            .collect();
        let s = Snapshots::uniform(0.1, cols);
        let d = Decomposition::new(&s).expect("svd");
        for (a, b) in d.singular_values().iter().zip(sig) {
            assert!((a - b).abs() < 1e-10 * b.max(1.0));
        }
        assert_eq!(d.numerical_rank(), 5);
        // E = 100/126.0101, 125/…, 126/…, 126.01/…, 1.
        assert_eq!(d.select_rank(RankSelection::Energy(0.5)).expect("r"), 1);
        assert_eq!(d.select_rank(RankSelection::Energy(0.99)).expect("r"), 2);
        assert_eq!(d.select_rank(RankSelection::Energy(0.9999)).expect("r"), 3);
        assert_eq!(d.select_rank(RankSelection::Energy(1.0)).expect("r"), 5);
        assert_eq!(d.select_rank(RankSelection::Rank(3)).expect("r"), 3);
        assert_eq!(d.select_rank(RankSelection::Rank(99)).expect("r"), 5);
        assert_eq!(d.select_rank(RankSelection::Full).expect("r"), 5);
        let model = fit(&s, RankSelection::Energy(0.99)).expect("fit");
        assert_eq!(model.rank(), 2);
        assert_eq!(model.selection(), RankSelection::Energy(0.99));
        let c = cumulative_energy(&[3.0, 4.0]);
        assert!((c[0] - 0.36).abs() < 1e-15 && (c[1] - 1.0).abs() < 1e-15);
        assert!(cumulative_energy(&[]).is_empty());
    }

    #[test]
    fn rom_error_decreases_with_rank() {
        // Modes of decreasing amplitude: (1.0, 0.3, 0.1, 0.03) on pairs, 0.01 on a real mode.
        let eigs =
            [Eig::Pair(0.999, 0.15), Eig::Pair(0.99, 0.5), Eig::Pair(0.98, 1.2), Eig::Pair(0.97, 2.0), Eig::Real(0.95)];
        let z0 = [1.0, 0.0, 0.3, 0.0, 0.1, 0.0, 0.03, 0.0, 0.01];
        let (mut s, _) = lifted_system(60, &eigs, &z0, 150, 0.02, 13);
        // Offset (a mean position) so that the relative error is well defined at every time.
        let mut rng = Rng(99);
        let offset: Vec<f64> = (0..60).map(|_| rng.normal()).collect();
        for c in &mut s.columns {
            c.iter_mut().zip(&offset).for_each(|(x, o)| *x += o);
        }
        let ranks = [1, 3, 5, 7, 9, 10];
        let rom = rom_error_vs_rank(&s, &ranks).expect("rom");
        eprintln!("ROM error vs rank: {rom:?}");
        assert_eq!(rom.iter().map(|p| p.0).collect::<Vec<_>>(), vec![1, 3, 5, 7, 9, 10]);
        for w in rom.windows(2) {
            assert!(w[1].1 <= w[0].1 * (1.0 + 1e-6) + 1e-12, "ROM error not decreasing: {rom:?}");
        }
        assert!(rom[0].1 > 1e-3 && rom[rom.len() - 1].1 < 1e-8, "{rom:?}");
        // Requests beyond the numerical rank are clamped and deduplicated.
        let rom2 = rom_error_vs_rank(&s, &[10, 50, 500]).expect("rom");
        assert_eq!(rom2.len(), 1);
        assert_eq!(default_rom_ranks(10, 3), vec![1, 2, 3, 4, 8, 10]);
    }

    // --- bad input ------------------------------------------------------------------------------------------

    #[test]
    fn bad_snapshots_give_errors_not_panics() {
        let ok = vec![vec![1.0, 2.0], vec![1.5, 2.5], vec![2.0, 2.0]];
        assert!(matches!(
            fit(&Snapshots::uniform(0.1, vec![]), RankSelection::Full),
            Err(DmdError::TooFewSnapshots { got: 0 })
        ));
        assert!(matches!(
            fit(&Snapshots::uniform(0.1, vec![vec![1.0]]), RankSelection::Full),
            Err(DmdError::TooFewSnapshots { got: 1 })
        ));
        let mut nan = ok.clone();
        nan[1][1] = f64::NAN;
        let e = fit(&Snapshots::uniform(0.1, nan), RankSelection::Full).expect_err("NaN");
        assert!(matches!(e, DmdError::NonFiniteSnapshot { index: 1, component: 1, .. }), "{e}");
        let ragged = vec![vec![1.0, 2.0], vec![1.0], vec![2.0, 2.0]];
        assert!(matches!(
            fit(&Snapshots::uniform(0.1, ragged), RankSelection::Full),
            Err(DmdError::RaggedSnapshot { index: 1, .. })
        ));
        assert!(matches!(
            fit(&Snapshots::uniform(0.1, ok.clone()), RankSelection::Rank(0)),
            Err(DmdError::InvalidRank)
        ));
        for e in [0.0, -0.5, 1.5, f64::NAN, f64::INFINITY] {
            let r = fit(&Snapshots::uniform(0.1, ok.clone()), RankSelection::Energy(e));
            assert!(matches!(r, Err(DmdError::InvalidEnergy { .. })), "energy {e}");
        }
        let zero = vec![vec![0.0; 3]; 4];
        assert!(matches!(fit(&Snapshots::uniform(0.1, zero), RankSelection::Full), Err(DmdError::ZeroData)));
        let empty = vec![vec![], vec![]];
        assert!(matches!(fit(&Snapshots::uniform(0.1, empty), RankSelection::Full), Err(DmdError::EmptyState)));
        let bad_t = Snapshots::new(vec![0.0, 0.1, 0.3], ok.clone());
        assert!(matches!(fit(&bad_t, RankSelection::Full), Err(DmdError::NonUniformTimes { .. })));
        let dec_t = Snapshots::new(vec![0.0, 0.0, 0.0], ok.clone());
        assert!(matches!(fit(&dec_t, RankSelection::Full), Err(DmdError::BadTime { .. })));
        let short_t = Snapshots::new(vec![0.0, 0.1], ok.clone());
        assert!(matches!(fit(&short_t, RankSelection::Full), Err(DmdError::TimeCountMismatch { .. })));
        // Dimension mismatch between a model and other snapshots.
        let model = fit(&Snapshots::uniform(0.1, ok), RankSelection::Full).expect("fit");
        let other = Snapshots::uniform(0.1, vec![vec![1.0; 3]; 3]);
        assert!(matches!(relative_error_vs_time(&model, &other, true), Err(DmdError::DimensionMismatch { .. })));
        assert!(matches!(mean_position_error(&other, &model, true), Err(DmdError::NoParticleLayout)));
        // CLI flag mapping.
        assert_eq!(rank_selection_from_cli(None, None).expect("full"), RankSelection::Full);
        assert_eq!(rank_selection_from_cli(Some(4), None).expect("rank"), RankSelection::Rank(4));
        assert!(matches!(rank_selection_from_cli(Some(4), Some(0.9)), Err(DmdError::ConflictingSelection)));
        assert!(matches!(rank_selection_from_cli(None, Some(1.2)), Err(DmdError::InvalidEnergy { .. })));
        assert!(matches!(rank_selection_from_cli(Some(0), None), Err(DmdError::InvalidRank)));
    }

    // --- 5. frame loading -----------------------------------------------------------------------------------

    const HEADER: &str = "phase,id,x,y,z,vx,vy,vz,density,n_s,n_l,pressure";

    /// Rows (phase, id, x, y, vx, vy) of a 2-D frame (z = 0.5, vz = 0), written in the given order.
    fn write_frame(dir: &Path, k: usize, rows: &[(&str, u64, f64, f64, f64, f64)]) {
        let mut text = format!("{HEADER}\n");
        for (ph, id, x, y, vx, vy) in rows {
            text.push_str(&format!("{ph},{id},{x:.9e},{y:.9e},5.000000000e-1,{vx:.6e},{vy:.6e},0.0,1000,0,1,0\n"));
        }
        std::fs::write(dir.join(format!("frame_{k:05}.csv")), text).expect("write frame");
    }

    fn particle_state(id: u64, k: usize) -> (f64, f64, f64, f64) {
        let t = k as f64 * 0.1;
        let p = id as f64;
        (p + 0.1 * t, 2.0 * p - 0.05 * t * t, 0.1 + p * 0.01, -0.1 * t)
    }

    fn write_shuffled_frames(dir: &Path, n_frames: usize) {
        let ids: [(&str, u64); 3] = [("liquid", 17), ("solid", 3), ("liquid", 2)];
        for k in 0..n_frames {
            let mut rows: Vec<(&str, u64, f64, f64, f64, f64)> = ids
                .iter()
                .map(|&(ph, id)| {
                    let (x, y, vx, vy) = particle_state(id, k);
                    (ph, id, x, y, vx, vy)
                })
                .collect();
            rows.rotate_left(k % 3);
            if k % 2 == 1 {
                rows.reverse();
            }
            write_frame(dir, k, &rows);
        }
    }

    #[test]
    fn load_frames_aligns_by_phase_and_id() {
        let dir = temp_dir("align");
        write_shuffled_frames(&dir, 5);
        std::fs::write(dir.join("summary.json"), "{}").expect("other file");
        let s = load_frames(&dir, 0.1, FrameFields { velocities: false }).expect("load");
        let layout = s.layout.as_ref().expect("layout");
        let keys: Vec<(Phase, u64)> = layout.particles.iter().map(|k| (k.phase, k.id)).collect();
        assert_eq!(keys, vec![(Phase::Liquid, 2), (Phase::Liquid, 17), (Phase::Solid, 3)]);
        assert_eq!(layout.components, vec![Component::X, Component::Y]);
        assert_eq!(layout.dropped.len(), 1);
        assert_eq!(layout.dropped[0].0, Component::Z);
        assert_eq!(s.len(), 5);
        assert!((s.times_s[4] - 0.4).abs() < 1e-15);
        for k in 0..5 {
            for (p, (_, id)) in keys.iter().enumerate() {
                let (x, y, _, _) = particle_state(*id, k);
                assert!((s.columns[k][2 * p] - x).abs() < 1e-8 * x.abs().max(1.0));
                assert!((s.columns[k][2 * p + 1] - y).abs() < 1e-8 * y.abs().max(1.0));
            }
        }
        let sv = load_frames(&dir, 0.1, FrameFields { velocities: true }).expect("load v");
        let lv = sv.layout.as_ref().expect("layout");
        assert_eq!(lv.components, vec![Component::X, Component::Y, Component::Vx, Component::Vy]);
        assert_eq!(sv.state_dim(), 12);
        let (_, _, vx, vy) = particle_state(17, 3);
        assert!((sv.columns[3][4 + 2] - vx).abs() < 1e-6 && (sv.columns[3][4 + 3] - vy).abs() < 1e-6);
        let sc = load_frames_components(&dir, 0.1, &[Component::Vx, Component::Vy, Component::Vz]).expect("load c");
        assert_eq!(sc.state_dim(), 9);
    }

    #[test]
    fn trailing_duplicate_frame_is_dropped() {
        let dir = temp_dir("dupframe");
        write_shuffled_frames(&dir, 4);
        let last = std::fs::read_to_string(dir.join("frame_00003.csv")).expect("read");
        std::fs::write(dir.join("frame_00004.csv"), last).expect("write");
        let s = load_frames(&dir, 0.1, FrameFields::default()).expect("load");
        assert_eq!(s.len(), 4);
        assert_eq!(s.layout.as_ref().map(|l| l.dropped_frames.clone()), Some(vec!["frame_00004.csv".to_string()]));
    }

    #[test]
    fn load_frames_errors_are_clear() {
        // Empty directory.
        let dir = temp_dir("empty");
        let e = load_frames(&dir, 0.1, FrameFields::default()).expect_err("empty");
        assert!(matches!(e, DmdError::NoFrames { .. }) && e.to_string().contains("frame_NNNNN.csv"), "{e}");
        // Bad interval.
        assert!(matches!(load_frames(&dir, 0.0, FrameFields::default()), Err(DmdError::InvalidInterval { .. })));
        // Missing directory.
        assert!(matches!(load_frames(&dir.join("nope"), 0.1, FrameFields::default()), Err(DmdError::Io { .. })));

        // Missing particle in frame 2.
        let dir = temp_dir("missing");
        write_shuffled_frames(&dir, 4);
        write_frame(&dir, 2, &[("liquid", 2, 0.0, 0.0, 0.0, 0.0), ("solid", 3, 1.0, 1.0, 0.0, 0.0)]);
        let e = load_frames(&dir, 0.1, FrameFields::default()).expect_err("missing");
        let msg = e.to_string();
        assert!(matches!(e, DmdError::MissingParticle { .. }), "{msg}");
        assert!(msg.contains("frame_00002.csv") && msg.contains("liquid id 17"), "{msg}");

        // Extra particle.
        write_frame(
            &dir,
            2,
            &[
                ("liquid", 2, 0.0, 0.0, 0.0, 0.0),
                ("liquid", 17, 0.0, 0.0, 0.0, 0.0),
                ("solid", 3, 1.0, 1.0, 0.0, 0.0),
                ("solid", 4, 1.0, 1.0, 0.0, 0.0),
            ],
        );
        let e = load_frames(&dir, 0.1, FrameFields::default()).expect_err("extra");
        assert!(matches!(e, DmdError::ExtraParticle { .. }) && e.to_string().contains("solid id 4"), "{e}");

        // Bad header.
        std::fs::write(dir.join("frame_00002.csv"), "phase,id,x,y\nliquid,2,0,0\n").expect("write");
        let e = load_frames(&dir, 0.1, FrameFields::default()).expect_err("header");
        let msg = e.to_string();
        assert!(
            matches!(e, DmdError::BadHeader { .. }) && msg.contains("frame_00002.csv") && msg.contains('z'),
            "{msg}"
        );

        // Non-numeric value.
        std::fs::write(dir.join("frame_00002.csv"), format!("{HEADER}\nliquid,2,0,abc,0.5,0,0,0,1,0,1,0\n"))
            .expect("w");
        let e = load_frames(&dir, 0.1, FrameFields::default()).expect_err("parse");
        let msg = e.to_string();
        assert!(
            matches!(e, DmdError::Parse { line: 2, .. }) && msg.contains("frame_00002.csv:2") && msg.contains("abc"),
            "{msg}"
        );

        // NaN value.
        std::fs::write(dir.join("frame_00002.csv"), format!("{HEADER}\nliquid,2,0,NaN,0.5,0,0,0,1,0,1,0\n"))
            .expect("w");
        assert!(matches!(load_frames(&dir, 0.1, FrameFields::default()), Err(DmdError::NonFiniteValue { .. })));

        // Unknown phase, short row, empty frame.
        std::fs::write(dir.join("frame_00002.csv"), format!("{HEADER}\ngas,2,0,0,0.5,0,0,0,1,0,1,0\n")).expect("w");
        assert!(matches!(load_frames(&dir, 0.1, FrameFields::default()), Err(DmdError::UnknownPhase { .. })));
        std::fs::write(dir.join("frame_00002.csv"), format!("{HEADER}\nliquid,2,0,0\n")).expect("w");
        assert!(matches!(load_frames(&dir, 0.1, FrameFields::default()), Err(DmdError::RowLength { .. })));
        std::fs::write(dir.join("frame_00002.csv"), format!("{HEADER}\n")).expect("w");
        assert!(matches!(load_frames(&dir, 0.1, FrameFields::default()), Err(DmdError::EmptyFrame { .. })));
        std::fs::write(dir.join("frame_00002.csv"), "").expect("w");
        assert!(matches!(load_frames(&dir, 0.1, FrameFields::default()), Err(DmdError::BadHeader { .. })));

        // Gap in the sequence.
        std::fs::remove_file(dir.join("frame_00002.csv")).expect("rm");
        let e = load_frames(&dir, 0.1, FrameFields::default()).expect_err("gap");
        assert!(matches!(e, DmdError::FrameGap { missing: 2, .. }), "{e}");

        // Duplicate particle within a frame.
        let dir2 = temp_dir("dup");
        write_frame(&dir2, 0, &[("liquid", 2, 0.0, 0.0, 0.0, 0.0), ("liquid", 2, 1.0, 0.0, 0.0, 0.0)]);
        assert!(matches!(load_frames(&dir2, 0.1, FrameFields::default()), Err(DmdError::DuplicateParticle { .. })));

        // A single frame loads, but DMD refuses it.
        write_frame(&dir2, 0, &[("liquid", 2, 0.0, 0.0, 0.0, 0.0), ("liquid", 5, 1.0, 0.3, 0.0, 0.0)]);
        let s = load_frames(&dir2, 0.1, FrameFields::default()).expect("one frame");
        assert!(matches!(fit(&s, RankSelection::Full), Err(DmdError::TooFewSnapshots { got: 1 })));
    }

    // --- 6. outputs -----------------------------------------------------------------------------------------

    /// A 2-D sloshing-like particle set: 40 particles displaced by a 0.5 Hz standing wave plus a weak
    /// 1.5 Hz harmonic, tank width 1 m.
    fn write_sloshing_frames(dir: &Path, n_frames: usize, dt: f64) {
        for k in 0..n_frames {
            let t = k as f64 * dt;
            let mut rows = Vec::new();
            for i in 0..8u64 {
                for j in 0..5u64 {
                    let (x0, y0) = (0.06 + 0.125 * i as f64, 0.05 + 0.08 * j as f64);
                    let w = 2.0 * PI * 0.5 * t;
                    let w3 = 2.0 * PI * 1.5 * t;
                    let dx = 0.05 * (PI * x0).cos() * w.sin() * (1.0 + y0) + 0.005 * (3.0 * PI * x0).sin() * w3.cos();
                    let dy = 0.03 * (PI * x0).sin() * w.cos() * y0;
                    rows.push(("liquid", 10 * i + j, x0 + dx, y0 + dy, 0.0, 0.0));
                }
            }
            rows.rotate_left(k % 7);
            write_frame(dir, k, &rows);
        }
    }

    #[test]
    fn write_outputs_creates_pngs_and_json() {
        let frames = temp_dir("frames_out");
        let dt = 0.05;
        write_sloshing_frames(&frames, 81, dt);
        let s = load_frames(&frames, dt, FrameFields::default()).expect("load");
        let model = fit(&s, RankSelection::Full).expect("fit");
        let fd = model.dominant_frequency_hz().expect("dominant");
        assert!((fd - 0.5).abs() < 1e-6, "dominant {fd}");
        let pe = mean_position_error(&s, &model, true).expect("position error");
        assert_eq!(pe.len(), s.len());
        assert!(pe.iter().all(|e| *e < 0.05 * 1.0), "max {}", pe.iter().fold(0.0f64, |a, b| a.max(*b)));
        let out = temp_dir("out");
        let report = write_outputs(&model, &s, &out).expect("write");
        for f in [
            "eigenvalues.png",
            "frequency_amplitude.png",
            "growth_rate_amplitude.png",
            "cumulative_energy.png",
            "reconstruction_error.png",
            "rom_error_vs_rank.png",
            "position_error.png",
        ] {
            let bytes = std::fs::read(out.join(f)).expect(f);
            assert!(bytes.len() > 1000 && bytes.starts_with(b"\x89PNG"), "{f}");
        }
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("dmd.json")).expect("json")).expect("parse");
        for key in [
            "eigenvalues",
            "amplitudes",
            "frequencies_hz",
            "growth_rates",
            "rank",
            "reconstruction_error",
            "dominant_frequency_hz",
            "singular_values",
            "rom_error_vs_rank",
            "cumulative_energy",
            "stabilised_eigenvalues",
        ] {
            assert!(json.get(key).is_some(), "dmd.json lacks {key}");
        }
        assert_eq!(json["rank"].as_u64(), Some(model.rank() as u64));
        assert_eq!(json["eigenvalues"].as_array().map(Vec::len), Some(model.rank()));
        assert!((json["dominant_frequency_hz"].as_f64().expect("f") - 0.5).abs() < 1e-6);
        // The 1.5 Hz harmonic has a single spatial pattern (a standing wave): a rank-deficient pair that linear
        // DMD can only approximate, hence a small but nonzero error.
        assert!(report.reconstruction_error < 5e-3, "{}", report.reconstruction_error);
        eprintln!(
            "sloshing: rank {}, rel err {:.3e}, max mean position error {:?} m, rom {:?}",
            report.rank, report.reconstruction_error, report.max_mean_position_error_m, report.rom_error_vs_rank
        );
        assert!(!report.rom_error_vs_rank.is_empty());
        // The CLI path end to end, with a truncated model.
        let out2 = out.join("energy");
        let r2 = run_dmd(
            &frames,
            dt,
            FrameFields::default(),
            RankSelection::Energy(0.99),
            AmplitudeFit::AllSnapshots,
            &out2,
        )
        .expect("run");
        assert!(r2.rank <= report.rank && r2.energy_at_rank >= 0.99);
        assert!(out2.join("dmd.json").exists());
    }
}
