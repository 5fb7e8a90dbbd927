//! The WGSL sources of the GPU back-end and the tiny `#import` resolver (STYLE §5.2, after vello's
//! `preprocess.rs` and rerun's `file_resolver.rs`). Sources are embedded at build time; a line
//! `#import common` is replaced by `shaders/common.wgsl`. Both pipeline creation (`passes.rs`) and
//! `tests/shader_validation.rs` call [`shader_source`], so the validated text is the text that runs.

/// Every shader file in `shaders/` (without `.wgsl`), with its text.
pub const SHADER_FILES: &[(&str, &str)] = &[
    ("common", include_str!("../../../shaders/common.wgsl")),
    ("grid", include_str!("../../../shaders/grid.wgsl")),
    ("density", include_str!("../../../shaders/density.wgsl")),
    ("solid", include_str!("../../../shaders/solid.wgsl")),
    ("forces", include_str!("../../../shaders/forces.wgsl")),
    ("integrate", include_str!("../../../shaders/integrate.wgsl")),
    ("dt", include_str!("../../../shaders/dt.wgsl")),
    ("fracture", include_str!("../../../shaders/fracture.wgsl")),
    ("batch", include_str!("../../../shaders/batch.wgsl")),
    ("emit", include_str!("../../../shaders/emit.wgsl")),
    ("ghosts", include_str!("../../../shaders/ghosts.wgsl")),
    // The renderer's passes (src/render/): same registry, same validation test.
    ("render_common", include_str!("../../../shaders/render_common.wgsl")),
    ("render_particles", include_str!("../../../shaders/render_particles.wgsl")),
    ("render_shapes", include_str!("../../../shaders/render_shapes.wgsl")),
    ("render_fluid", include_str!("../../../shaders/render_fluid.wgsl")),
];

/// Why a shader could not be resolved.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
#[non_exhaustive]
pub enum ShaderError {
    #[error("no shader named `{0}` (register it in src/sim/gpu/shaders.rs SHADER_FILES)")]
    Unknown(String),
    #[error("shader `{file}` line {line}: `#import {name}` names no shader")]
    BadImport { file: String, line: usize, name: String },
}

fn raw(name: &str) -> Option<&'static str> {
    SHADER_FILES.iter().find(|(n, _)| *n == name).map(|(_, s)| *s)
}

/// The resolved WGSL of shader `name` (each `#import x` replaced by the text of `x`, once).
pub fn shader_source(name: &str) -> Result<String, ShaderError> {
    let text = raw(name).ok_or_else(|| ShaderError::Unknown(name.to_string()))?;
    let mut out = String::with_capacity(text.len() + 16 * 1024);
    let mut imported: Vec<&str> = Vec::new();
    for (k, line) in text.lines().enumerate() {
        if let Some(rest) = line.trim_start().strip_prefix("#import") {
            let what = rest.trim();
            let src = raw(what).ok_or_else(|| ShaderError::BadImport {
                file: name.to_string(),
                line: k + 1,
                name: what.to_string(),
            })?;
            if !imported.contains(&what) {
                imported.push(what);
                out.push_str(src);
                out.push('\n');
            }
        } else {
            out.push_str(line);
            out.push('\n');
        }
    }
    Ok(out)
}
