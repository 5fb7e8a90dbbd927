//! Offscreen PNG frames of a validation run (the rendered frames the medical cases hand in), drawn with
//! the viewer's renderer on whatever adapter there is (a GPU or lavapipe).

use crate::scenario::Scenario;
use crate::sim::{BackendKind, SimError, Simulation};
use std::path::{Path, PathBuf};

/// Offscreen frames of a run (the rendered PNGs the issue asks for), when an adapter (a GPU or
/// lavapipe) is there; without one the run goes on without pictures.
pub(crate) struct Frames {
    ctx: crate::sim::gpu::GpuContext,
    renderer: crate::render::Renderer,
    camera: Option<crate::render::OrbitCamera>,
    dir: PathBuf,
    prefix: String,
}

impl Frames {
    pub(crate) fn new(dir: &Path, prefix: &str) -> Option<Frames> {
        let ctx = crate::sim::gpu::GpuContext::new()
            .map_err(|e| log::warn!("no adapter for the validation frames ({e}); running without them"))
            .ok()?;
        let renderer = crate::render::Renderer::new(&ctx.device, &ctx.queue)
            .map_err(|e| log::warn!("cannot render the validation frames: {e}"))
            .ok()?;
        Some(Frames { ctx, renderer, camera: None, dir: dir.to_path_buf(), prefix: prefix.to_string() })
    }

    /// Writes `<prefix>_<tag>.png` (1280×720) of the current state; the camera is fitted on the first.
    pub(crate) fn shoot(&mut self, sim: &Simulation, tag: &str) {
        let camera = self.camera.get_or_insert_with(|| crate::render::snapshot::default_camera(sim));
        let path = self.dir.join(format!("{}_{tag}.png", self.prefix));
        match crate::render::snapshot::render_image(sim, &self.ctx, &mut self.renderer, camera, (1280, 720)) {
            Ok(img) => match img.save(&path) {
                Ok(()) => log::info!("rendered {} at t = {:.3} s", path.display(), sim.time()),
                Err(e) => log::warn!("cannot write {}: {e}", path.display()),
            },
            Err(e) => log::warn!("cannot render {}: {e}", path.display()),
        }
    }
}

/// The simulation of a validation run and, with `frames` = (dir, prefix), its frame writer: a GPU run
/// shares the renderer's device (the frames read its buffers), a CPU run renders on any adapter.
pub(crate) fn simulation_with_frames(
    sc: &Scenario,
    backend: BackendKind,
    frames: Option<(&Path, &str)>,
) -> Result<(Simulation, Option<Frames>), SimError> {
    let frames = frames.and_then(|(dir, prefix)| Frames::new(dir, prefix));
    let sim = match (&frames, backend) {
        (Some(f), BackendKind::Gpu) => Simulation::with_gpu(sc, Some(f.ctx.clone()))?,
        _ => Simulation::new(sc, backend)?,
    };
    Ok((sim, frames))
}
