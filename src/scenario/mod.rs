//! What is simulated: the RON scenario format (`schema`), its validation with messages that name the
//! file, the field and the fix (`validate`), `--set FIELD=VALUE` overrides, and the particle generators
//! that turn a scenario into initial particle sets (`generate`).
//!
//! Loading never panics on user input: every failure is a [`ScenarioError`].

mod generate;
pub mod liver;
pub mod mesh;
mod ron_path;
mod schema;
mod validate;

pub use generate::{
    BoundaryObject, DEFAULT_EMITTER_ROOM, EmitterSlots, GeneratedParticles, PhaseParticles, SolidFlags,
    cantilever_mode, generate, lattice_points, motion_at,
};
pub use schema::*;
pub use validate::{MAX_OUTLETS, MAX_TENSION_REGIONS, warnings};

use std::path::Path;

/// Errors of loading, overriding or validating a scenario. Messages name the field and the fix,
/// and end with the file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ScenarioError {
    #[error("cannot read scenario file: {source} — check the path and permissions [{path}]")]
    Io { path: String, source: std::io::Error },
    #[error("line {line}, column {col}: {message} — {fix} [{path}]")]
    Syntax { path: String, line: usize, col: usize, message: String, fix: String },
    #[error("invalid `{field}`: {problem} — {fix} [{path}]")]
    Invalid { path: String, field: String, problem: String, fix: String },
    #[error("bad override `--set {spec}`: {problem} — {fix}")]
    Override { spec: String, problem: String, fix: String },
}

/// A problem found by validation, before the file name is attached.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    pub field: String,
    pub problem: String,
    pub fix: String,
}

impl Problem {
    fn into_error(self, path: &str) -> ScenarioError {
        ScenarioError::Invalid { path: path.to_string(), field: self.field, problem: self.problem, fix: self.fix }
    }
}

impl Scenario {
    /// Reads, parses and validates a scenario file.
    pub fn load(path: &Path) -> Result<Scenario, ScenarioError> {
        Scenario::load_with_overrides(path, &[])
    }

    /// Reads and parses a scenario file, applies `FIELD=VALUE` overrides, then validates.
    pub fn load_with_overrides(path: &Path, overrides: &[String]) -> Result<Scenario, ScenarioError> {
        let shown = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Io { path: shown.clone(), source })?;
        Scenario::from_str_with_overrides(&text, &shown, overrides)
    }

    /// Parses and validates scenario text; `origin` names it in messages.
    pub fn from_str_named(text: &str, origin: &str) -> Result<Scenario, ScenarioError> {
        Scenario::from_str_with_overrides(text, origin, &[])
    }

    pub fn from_str_with_overrides(text: &str, origin: &str, overrides: &[String]) -> Result<Scenario, ScenarioError> {
        let mut scenario: Scenario = ron::Options::default().from_str(text).map_err(|e| syntax_error(e, origin))?;
        for spec in overrides {
            scenario = scenario.with_override(spec)?;
        }
        scenario.base_dir = std::path::Path::new(origin).parent().map(|d| d.to_path_buf());
        validate::validate(&scenario).map_err(|p| p.into_error(origin))?;
        Ok(scenario)
    }

    /// Validates an in-memory scenario (used after programmatic changes).
    pub fn validate(&self, origin: &str) -> Result<(), ScenarioError> {
        validate::validate(self).map_err(|p| p.into_error(origin))
    }

    /// Applies one `FIELD=VALUE` override (dotted path, e.g. `numerics.dx_liquid=0.0005`,
    /// `particles.0.max=(0.01, 0.02, 0)`, `boundaries.1.shape=Sphere(centre: (0, 0, 0.1), radius: 0.01)`).
    /// Enum wrappers and `Some` in the path may be omitted. The value is RON typed by the field it
    /// replaces (`ron_path`); where RON refuses it, the untyped shorthands still apply (a bare number for
    /// an optional field, `null` for `None`; text that is not RON at all is taken as a string).
    /// The result is not validated yet: callers validate once after all overrides.
    pub fn with_override(&self, spec: &str) -> Result<Scenario, ScenarioError> {
        let err = |problem: String, fix: &str| ScenarioError::Override {
            spec: spec.to_string(),
            problem,
            fix: fix.to_string(),
        };
        let (field, value) = spec
            .split_once('=')
            .ok_or_else(|| err("missing `=`".into(), "write FIELD=VALUE, e.g. numerics.dx_liquid=0.0005"))?;
        let (field, text) = (field.trim(), value.trim());
        if text.parse::<f64>().is_ok_and(|x| !x.is_finite()) {
            return Err(err(format!("`{text}` is not a finite number"), "give a number, a boolean or a RON value"));
        }
        // 1. typed: the value spliced into the scenario's own RON
        let typed = ron::to_string(self)
            .map_err(|e| e.to_string())
            .and_then(|own| ron_path::splice(&own, field, text))
            .map(|spliced| ron::Options::default().from_str::<Scenario>(&spliced).map_err(|e| e.code.to_string()));
        let typed_problem = match typed {
            Ok(Ok(mut sc)) => {
                sc.base_dir.clone_from(&self.base_dir);
                return Ok(sc);
            }
            Ok(Err(problem)) => Some(problem),
            Err(_) => None, // a path problem: the untyped route says it in its words
        };
        // 2. untyped, through JSON: a bare number or null for an `Option`, RON without variant names
        let value = parse_override_value(text).map_err(|p| err(p, "give a number, a boolean or a RON value"))?;
        let mut tree = serde_json::to_value(self).map_err(|e| err(e.to_string(), "report this as a bug"))?;
        set_path(&mut tree, field).map(|slot| *slot = value).map_err(|p| {
            err(p, "use a dotted path of the scenario schema (README: Scenario format), e.g. numerics.h_over_dx")
        })?;
        let mut sc: Scenario = serde_json::from_value(tree).map_err(|e| {
            // the typed route's message names the field's type and variants
            err(
                typed_problem.unwrap_or_else(|| e.to_string()),
                "give a value of the field's type, in RON as in the file",
            )
        })?;
        sc.base_dir.clone_from(&self.base_dir);
        Ok(sc)
    }

    /// Number of spatial dimensions as a kernel enum.
    pub fn dim(&self) -> crate::sim::kernels::Dim {
        if self.dimensions == 2 { crate::sim::kernels::Dim::Two } else { crate::sim::kernels::Dim::Three }
    }
}

fn syntax_error(e: ron::error::SpannedError, path: &str) -> ScenarioError {
    use ron::Error as E;
    let fix = match &e.code {
        E::NoSuchStructField { .. } => {
            "remove the field or correct its spelling (the message lists the expected fields)"
        }
        E::MissingStructField { .. } => "add the field (README: Scenario format lists every field with its unit)",
        E::NoSuchEnumVariant { .. } => "use one of the listed variants",
        E::DuplicateStructField { .. } => "keep only one of the duplicated fields",
        _ => "fix the RON syntax at that position (balanced parentheses, commas between fields, `field: value`)",
    };
    ScenarioError::Syntax {
        path: path.to_string(),
        line: e.span.start.line,
        col: e.span.start.col,
        message: e.code.to_string(),
        fix: fix.to_string(),
    }
}

fn parse_override_value(text: &str) -> Result<serde_json::Value, String> {
    // Integers stay integers (counts such as `liquid_capacity`); serde turns them into floats where a
    // float is expected.
    if let Ok(n) = text.parse::<i64>() {
        return Ok(serde_json::Value::from(n));
    }
    if let Ok(x) = text.parse::<f64>() {
        if !x.is_finite() {
            return Err(format!("`{text}` is not a finite number"));
        }
        return serde_json::to_value(x).map_err(|e| e.to_string());
    }
    if let Ok(v) = serde_json::from_str::<serde_json::Value>(text) {
        return Ok(v);
    }
    if let Ok(v) = ron::from_str::<ron::Value>(text) {
        return serde_json::to_value(v).map_err(|e| e.to_string());
    }
    Ok(serde_json::Value::String(text.to_string()))
}

fn set_path<'a>(tree: &'a mut serde_json::Value, field: &str) -> Result<&'a mut serde_json::Value, String> {
    let mut node = tree;
    for seg in field.split('.') {
        // Step through an externally tagged enum wrapper (`{"Box": {...}}`) that the path omits.
        let through_wrapper = matches!(&*node, serde_json::Value::Object(map)
            if map.len() == 1
                && !map.contains_key(seg)
                && map.keys().all(|k| k.starts_with(|c: char| c.is_ascii_uppercase())));
        if through_wrapper && let serde_json::Value::Object(map) = node {
            node = map.values_mut().next().ok_or("empty enum wrapper")?;
        }
        node = match node {
            serde_json::Value::Object(map) => map.get_mut(seg).ok_or_else(|| format!("no field `{seg}` here"))?,
            serde_json::Value::Array(items) => {
                let i: usize = seg.parse().map_err(|_| format!("`{seg}` is not a list index"))?;
                let n = items.len();
                items.get_mut(i).ok_or_else(|| format!("index {i} out of range (list has {n} entries)"))?
            }
            _ => return Err(format!("`{seg}` goes below a plain value")),
        };
    }
    Ok(node)
}
