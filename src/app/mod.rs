//! The interactive viewer: the winit event loop, egui and rendering on the main thread; the
//! simulation on its own thread (`sim_thread`), sharing one wgpu device and two render buffer sets.
//! Input becomes commands on a channel (`tools`, `ui`); the renderer draws whatever set was published
//! last, so frame rate and step rate are independent and the window keeps drawing while the
//! simulation is paused, slow or diverged.

pub mod sim_thread;
pub mod tools;
pub mod ui;

use crate::render::{OrbitCamera, Renderer, Scene, snapshot};
use crate::scenario::{Scenario, ToolKind};
use crate::sim::Command;
use crate::sim::gpu::GpuContext;
use glam::Vec3;
use sim_thread::{Control, Shared, lock};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc::Sender;
use std::time::Instant;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

/// How the viewer starts.
#[derive(Clone, Debug)]
pub struct ViewerOptions {
    pub scenario: Scenario,
    pub scenario_path: PathBuf,
    /// Run the simulation on the GPU (shared device) rather than on the CPU.
    pub gpu_simulation: Option<bool>,
    /// Quit after this many frames (smoke tests, screenshots for the README).
    pub frames: Option<u64>,
    /// Save the last frame (window contents, panels included) as PNG.
    pub screenshot: Option<PathBuf>,
    pub size: (u32, u32),
    pub paused: bool,
    /// Record the session (the first scenario run) to this file (`perfuse replay FILE --verify`).
    pub record: Option<PathBuf>,
    /// Replay this recording (with its timeline) instead of running `scenario` live; `scenario`
    /// should be the recording's own.
    pub replay: Option<crate::replay::format::Recording>,
    /// Start the live run paced at this many simulated seconds per wall second (`--pace`).
    pub pace: Option<f64>,
    /// Keep relaxed states here between launches and start from them
    /// (`replay::relaxed_cache::RelaxedCache::user_default()`; `None`: relax every time).
    pub relaxed_cache: Option<crate::replay::relaxed_cache::RelaxedCache>,
    /// Relax live even when a relaxed state is cached (`--fresh-relaxation`; the new one replaces it).
    pub fresh_relaxation: bool,
}

/// Why the viewer could not run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum AppError {
    #[error(
        "cannot open a window: {0}. Is there a display (DISPLAY / WAYLAND_DISPLAY)? On a headless machine use \
         `xvfb-run -a perfuse …`, or the headless commands `perfuse run`, `perfuse render`, `perfuse bench`"
    )]
    NoDisplay(String),
    #[error("GPU: {0}")]
    Gpu(String),
    #[error("renderer: {0}")]
    Render(#[from] crate::render::RenderError),
    #[error("screenshot {path}: {message}")]
    Screenshot { path: String, message: String },
}

/// What a finished viewer session reports (frames drawn, rates seen).
#[derive(Clone, Debug, Default)]
pub struct ViewerReport {
    pub frames: u64,
    pub fps: f64,
    pub sim_steps: u64,
    /// Scenarios with a patient: the session's metrics at the end.
    pub session: Option<crate::analysis::session::SessionReport>,
    pub steps_per_s: f64,
    pub screenshot: Option<PathBuf>,
}

/// Opens the viewer and runs until the window closes (or `frames` frames were drawn).
pub fn run(opts: ViewerOptions) -> Result<ViewerReport, AppError> {
    let event_loop = EventLoop::new().map_err(|e| AppError::NoDisplay(e.to_string()))?;
    let mut app = App { opts, gfx: None, error: None, report: ViewerReport::default() };
    event_loop.run_app(&mut app).map_err(|e| AppError::NoDisplay(e.to_string()))?;
    if let Some(e) = app.error.take() {
        return Err(e);
    }
    if let Some(g) = app.gfx.take() {
        let _ = g.tx.send(Control::Quit);
        if let Some(h) = g.sim_thread {
            let _ = h.join();
        }
    }
    Ok(app.report)
}

struct App {
    opts: ViewerOptions,
    gfx: Option<Gfx>,
    error: Option<AppError>,
    report: ViewerReport,
}

/// Everything that exists once the window does.
struct Gfx {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    ctx: GpuContext,
    renderer: Renderer,
    egui_ctx: egui::Context,
    egui_state: egui_winit::State,
    egui_renderer: egui_wgpu::Renderer,
    tx: Sender<Control>,
    shared: Arc<Shared>,
    sim_thread: Option<std::thread::JoinHandle<()>>,
    /// Bind groups of the two published sets, for the set generation they were made for.
    bind_groups: Option<(u64, [wgpu::BindGroup; 2])>,
    camera: OrbitCamera,
    camera_fitted_for: u64,
    ui: ui::UiState,
    tools: tools::ToolInput,
    scenario: Scenario,
    cursor: (f32, f32),
    buttons: (bool, bool, bool),
    modifiers: winit::keyboard::ModifiersState,
    frames: u64,
    last_frame: Instant,
    stats: ui::FrameStats,
    screenshot_next: Option<PathBuf>,
    /// Top of the scenario's material along the camera's up axis (generated once per scenario: the
    /// liver's mesh sampling is too slow to repeat on every mouse move).
    material_top: Option<f32>,
}

impl App {
    fn init(&mut self, event_loop: &ActiveEventLoop) -> Result<Gfx, AppError> {
        let attrs = Window::default_attributes()
            .with_title(format!("Perfuse — {}", self.opts.scenario.name))
            .with_inner_size(winit::dpi::PhysicalSize::new(self.opts.size.0, self.opts.size.1));
        let window = Arc::new(event_loop.create_window(attrs).map_err(|e| AppError::NoDisplay(e.to_string()))?);
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: wgpu::Backends::VULKAN | wgpu::Backends::METAL | wgpu::Backends::DX12,
            flags: wgpu::InstanceFlags::from_build_config()
                .with_env()
                .difference(wgpu::InstanceFlags::VALIDATION_INDIRECT_CALL),
            ..wgpu::InstanceDescriptor::new_with_display_handle(Box::new(event_loop.owned_display_handle()))
        });
        let surface = instance.create_surface(window.clone()).map_err(|e| AppError::Gpu(e.to_string()))?;
        let adapter = pick_adapter(&instance, &surface)?;
        let ctx = GpuContext::from_adapter(&adapter).map_err(|e| AppError::Gpu(e.to_string()))?;
        let size = window.inner_size();
        let mut config = surface
            .get_default_config(&adapter, size.width.max(1), size.height.max(1))
            .ok_or_else(|| AppError::Gpu(format!("adapter `{}` cannot present to this window", ctx.info.name)))?;
        let caps = surface.get_capabilities(&adapter);
        // egui wants a non-sRGB framebuffer; the 3-D view is written through an sRGB view of it.
        if let Some(f) = caps.formats.iter().find(|f| !f.is_srgb() && f.add_srgb_suffix().is_srgb()) {
            config.format = *f;
            config.view_formats = vec![f.add_srgb_suffix()];
        }
        // Screenshots copy the presented frame, panels included.
        if caps.usages.contains(wgpu::TextureUsages::COPY_SRC) {
            config.usage |= wgpu::TextureUsages::COPY_SRC;
        }
        config.present_mode = wgpu::PresentMode::AutoVsync;
        surface.configure(&ctx.device, &config);
        let renderer = Renderer::new(&ctx.device, &ctx.queue)?;
        let egui_ctx = egui::Context::default();
        let egui_state = egui_winit::State::new(
            egui_ctx.clone(),
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            None,
            Some(ctx.limits.max_texture_dimension_2d as usize),
        );
        let egui_renderer = egui_wgpu::Renderer::new(&ctx.device, config.format, egui_wgpu::RendererOptions::default());
        let (tx, rx) = std::sync::mpsc::channel();
        let shared = Arc::new(Shared::default());
        // The simulation runs on the GPU when it is a hardware one (or when asked), else on the CPU.
        let gpu_sim = self.opts.gpu_simulation.unwrap_or(ctx.info.device_type != wgpu::DeviceType::Cpu);
        let start = sim_thread::Start {
            use_gpu: gpu_sim,
            scenario: self.opts.scenario.clone(),
            paused: self.opts.paused,
            record: self.opts.record.clone(),
            replay: self.opts.replay.clone(),
            relaxed_cache: self.opts.relaxed_cache.clone(),
            fresh_relaxation: self.opts.fresh_relaxation,
        };
        let sim_thread = sim_thread::spawn_with(ctx.clone(), start, rx, shared.clone())
            .map_err(|e| AppError::Gpu(format!("could not start the simulation thread: {e}")))?;
        if self.opts.pace.is_some() {
            let _ = tx.send(Control::Pace(self.opts.pace));
        }
        let mut ui_state = ui::UiState {
            scenarios: ui::shipped_scenarios(),
            current: self.opts.scenario_path.clone(),
            show_help: false,
            gravity_on: true,
            gravity_scale: 1.0,
            tool_speed: 1.0,
            tools_available: Vec::new(),
            selected_tool: None,
            last_screenshot: None,
            scrub: None,
            scenario_warnings: crate::scenario::warnings(&self.opts.scenario),
        };
        ui_state.tools_available = tools_of(&self.opts.scenario);
        let stats = ui::FrameStats {
            adapter: format!("{} ({:?})", ctx.info.name, ctx.info.backend),
            size: (config.width, config.height),
            ..Default::default()
        };
        log::info!(
            "viewer on {} ({:?}), simulation on the {}",
            ctx.info.name,
            ctx.info.backend,
            if gpu_sim { "GPU" } else { "CPU" }
        );
        Ok(Gfx {
            window,
            surface,
            config,
            ctx,
            renderer,
            egui_ctx,
            egui_state,
            egui_renderer,
            tx,
            shared,
            sim_thread: Some(sim_thread),
            bind_groups: None,
            camera: OrbitCamera::default(),
            camera_fitted_for: 0,
            ui: ui_state,
            tools: tools::ToolInput::default(),
            scenario: self.opts.scenario.clone(),
            cursor: (0.0, 0.0),
            buttons: (false, false, false),
            modifiers: Default::default(),
            frames: 0,
            last_frame: Instant::now(),
            stats,
            screenshot_next: None,
            material_top: None,
        })
    }
}

/// Seconds since the Unix epoch (file names of recordings and screenshots).
fn unix_stamp() -> u64 {
    std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0)
}

/// The tool kinds a scenario offers, in palette order.
fn tools_of(s: &Scenario) -> Vec<ToolKind> {
    let mut v: Vec<ToolKind> = s.boundaries.iter().filter_map(|b| b.tool.as_ref().map(|t| t.kind)).collect();
    v.sort_by_key(|k| *k as u8);
    v.dedup();
    v
}

/// An adapter that can present to `surface`: `PERFUSE_ADAPTER` if set, else hardware first, else the
/// Vulkan software adapter (never GL).
fn pick_adapter(instance: &wgpu::Instance, surface: &wgpu::Surface) -> Result<wgpu::Adapter, AppError> {
    let wanted = std::env::var("PERFUSE_ADAPTER").ok().filter(|s| !s.is_empty());
    crate::sim::gpu::device::select_adapter_where(instance, wanted.as_deref(), false, |a| {
        a.is_surface_supported(surface)
    })
    .map_err(|e| AppError::Gpu(format!("no adapter can present to the window: {e}")))
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.gfx.is_some() {
            return;
        }
        match self.init(event_loop) {
            Ok(g) => {
                g.window.request_redraw();
                self.gfx = Some(g);
            }
            Err(e) => {
                self.error = Some(e);
                event_loop.exit();
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(g) = self.gfx.as_mut() else { return };
        let consumed = g.egui_state.on_window_event(&g.window, &event).consumed;
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => {
                g.config.width = size.width.max(1);
                g.config.height = size.height.max(1);
                g.surface.configure(&g.ctx.device, &g.config);
                g.stats.size = (g.config.width, g.config.height);
            }
            WindowEvent::ModifiersChanged(m) => g.modifiers = m.state(),
            WindowEvent::RedrawRequested => {
                match g.redraw() {
                    Ok(()) => {}
                    Err(e) => {
                        self.error = Some(e);
                        event_loop.exit();
                        return;
                    }
                }
                self.report.frames = g.frames;
                self.report.fps = g.stats.fps;
                {
                    let st = lock(&g.shared.status);
                    self.report.sim_steps = st.steps;
                    self.report.session = st.session.clone();
                    self.report.steps_per_s = st.steps_per_s;
                }
                if let Some(n) = self.opts.frames {
                    if g.frames + 1 == n
                        && let Some(p) = &self.opts.screenshot
                    {
                        g.screenshot_next = Some(p.clone());
                        self.report.screenshot = Some(p.clone());
                    }
                    if g.frames >= n {
                        event_loop.exit();
                        return;
                    }
                }
                g.window.request_redraw();
            }
            _ if consumed => {}
            WindowEvent::CursorMoved { position, .. } => {
                let p = (position.x as f32, position.y as f32);
                let (dx, dy) = (p.0 - g.cursor.0, p.1 - g.cursor.1);
                g.cursor = p;
                let h = g.config.height as f32;
                if g.buttons.1 && !g.modifiers.control_key() {
                    g.camera.orbit(dx * 0.008, dy * 0.008);
                } else if g.buttons.2 || (g.buttons.1 && g.modifiers.control_key()) {
                    g.camera.pan(dx / h, dy / h);
                } else if g.buttons.0 {
                    g.tool_drag();
                }
            }
            WindowEvent::MouseInput { state, button, .. } => {
                let down = state == ElementState::Pressed;
                match button {
                    MouseButton::Left => {
                        g.buttons.0 = down;
                        if down {
                            g.tool_press();
                        } else {
                            g.tools.release();
                        }
                    }
                    MouseButton::Right => g.buttons.1 = down,
                    MouseButton::Middle => g.buttons.2 = down,
                    _ => {}
                }
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                if g.modifiers.shift_key() {
                    g.tool_height(-lines);
                } else {
                    g.camera.zoom(0.9f32.powf(lines));
                }
            }
            WindowEvent::KeyboardInput { event, .. }
                if event.state == ElementState::Pressed && g.key(&event.logical_key) =>
            {
                event_loop.exit();
            }
            _ => {}
        }
    }
}

impl Gfx {
    fn send(&self, c: Control) {
        // The simulation thread outlives the window; a send fails only after it ended.
        if self.tx.send(c).is_err() {
            log::warn!("simulation thread has stopped");
        }
    }

    fn tool_scene_data(&self) -> (Vec<crate::sim::ObjectPose>, [f64; 3]) {
        let p = lock(&self.shared.published);
        (p.info.objects.clone(), p.info.origin)
    }

    fn with_tool_scene<R>(&self, f: impl FnOnce(&tools::ToolScene) -> R) -> R {
        let (objects, origin) = self.tool_scene_data();
        let to_sim = |v: [f64; 3]| snapshot::to_sim(v, origin);
        let d = &self.scenario.domain;
        let (dx_s, dx_l) = snapshot::spacings(&self.scenario);
        let up = self.camera.up;
        // Top of the tissue: the highest generated material point along `up`.
        let top = self.material_top.unwrap_or_else(|| self.compute_material_top(up, origin));
        let scene = tools::ToolScene {
            objects: &objects,
            origin,
            up,
            top,
            domain_min: to_sim(d.min),
            domain_max: to_sim(d.max),
            dx: dx_s.min(dx_l),
        };
        f(&scene)
    }

    fn compute_material_top(&self, up: Vec3, origin: [f64; 3]) -> f32 {
        snapshot::material_points(&self.scenario, origin)
            .iter()
            .map(|p| p.dot(up))
            .fold(f32::NEG_INFINITY, f32::max)
            .max(-1e3)
    }

    fn size_f(&self) -> (f32, f32) {
        (self.config.width as f32, self.config.height as f32)
    }

    fn tool_press(&mut self) {
        let (cursor, size, camera) = (self.cursor, self.size_f(), self.camera.clone());
        let mut tools = self.tools.clone();
        let cmds = self.with_tool_scene(|s| tools.press(s, &camera, cursor, size));
        self.tools = tools;
        for c in cmds {
            self.send(Control::Sim(c));
        }
    }

    fn tool_drag(&mut self) {
        let (cursor, size, camera) = (self.cursor, self.size_f(), self.camera.clone());
        let mut tools = self.tools.clone();
        let cmds = self.with_tool_scene(|s| tools.drag(s, &camera, cursor, size));
        self.tools = tools;
        for c in cmds {
            self.send(Control::Sim(c));
        }
    }

    fn tool_height(&mut self, steps: f32) {
        let mut tools = self.tools.clone();
        self.with_tool_scene(|s| tools.adjust_height(2.0 * steps, s));
        self.tools = tools;
        if self.tools.dragging {
            // Re-target at the new height even without cursor motion.
            self.tools.dragging = true;
            let (cursor, size, camera) = (self.cursor, self.size_f(), self.camera.clone());
            let mut tools = self.tools.clone();
            let cmds = self.with_tool_scene(|s| tools.drag(s, &camera, (cursor.0 + 0.01, cursor.1), size));
            self.tools = tools;
            for c in cmds {
                self.send(Control::Sim(c));
            }
        }
    }

    /// A key press; returns true to quit.
    fn key(&mut self, key: &Key) -> bool {
        let paused = lock(&self.shared.status).paused;
        match key {
            Key::Named(NamedKey::Escape) => return true,
            Key::Named(NamedKey::Space) => self.act(ui::UiAction::Pause(!paused)),
            Key::Character(c) => match c.as_str() {
                "s" => self.act(ui::UiAction::Step),
                "r" => self.act(ui::UiAction::Reset),
                "h" => self.ui.show_help = !self.ui.show_help,
                "v" => {
                    let on = lock(&self.shared.status).recording.is_none();
                    self.act(ui::UiAction::Record(on));
                }
                "t" => self.act(ui::UiAction::TakeOver { branch: false }),
                "p" => self.act(ui::UiAction::Screenshot),
                "c" => self.act(ui::UiAction::ResetCamera),
                "b" => self.renderer.settings.fluid = !self.renderer.settings.fluid,
                "f" => {
                    let all = crate::render::FieldMode::ALL;
                    let i = all.iter().position(|f| *f == self.renderer.settings.field).unwrap_or(0);
                    let next = all[(i + 1) % all.len()];
                    self.renderer.settings.field = next;
                    self.renderer.settings.field_scale = next.default_scale();
                }
                "q" => self.tool_height(-1.0),
                "e" => self.tool_height(1.0),
                "0" => self.act(ui::UiAction::SelectTool(None)),
                d @ ("1" | "2" | "3") => {
                    let k = d.parse::<usize>().unwrap_or(1) - 1;
                    if let Some(t) = self.ui.tools_available.get(k).copied() {
                        self.act(ui::UiAction::SelectTool(Some(t)));
                    }
                }
                _ => {}
            },
            _ => {}
        }
        false
    }

    /// The scenario's gravity × the live scale, or none when switched off.
    fn send_gravity(&self) {
        let k = if self.ui.gravity_on { self.ui.gravity_scale } else { 0.0 };
        let g = self.scenario.gravity.map(|x| x * k);
        self.send(Control::Sim(Command::SetGravity(g)));
    }

    fn act(&mut self, a: ui::UiAction) {
        match a {
            ui::UiAction::Pause(p) => self.send(Control::Pause(p)),
            ui::UiAction::Step => self.send(Control::Step),
            ui::UiAction::Reset => {
                self.send(Control::Reset);
                self.ui.gravity_on = true;
                self.ui.gravity_scale = 1.0;
            }
            ui::UiAction::Load(p) => match Scenario::load(&p) {
                Ok(s) => {
                    // on stderr as the command line prints them, and under the picker
                    self.ui.scenario_warnings = crate::scenario::warnings(&s);
                    for w in &self.ui.scenario_warnings {
                        eprintln!("warning: scenario `{}`, {w}", s.name);
                    }
                    self.ui.current = p;
                    self.ui.tools_available = tools_of(&s);
                    self.ui.selected_tool = None;
                    self.tools.selected = None;
                    self.ui.gravity_on = true;
                    self.ui.gravity_scale = 1.0;
                    self.scenario = s.clone();
                    self.window.set_title(&format!("Perfuse — {}", s.name));
                    self.send(Control::Load(Box::new(s)));
                }
                Err(e) => lock(&self.shared.status).error = Some(e.to_string()),
            },
            ui::UiAction::SelectTool(t) => {
                self.ui.selected_tool = t;
                self.tools.selected = t;
            }
            ui::UiAction::Gravity(on) => {
                self.ui.gravity_on = on;
                self.send_gravity();
            }
            ui::UiAction::GravityScale(k) => {
                self.ui.gravity_scale = k.clamp(0.0, 2.0);
                self.send_gravity();
            }
            ui::UiAction::Screenshot => {
                let dir = PathBuf::from("screenshots");
                let stamp = std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map(|d| d.as_secs())
                    .unwrap_or(0);
                self.screenshot_next = Some(dir.join(format!("perfuse-{stamp}.png")));
            }
            ui::UiAction::ResetCamera => self.camera_fitted_for = 0,
            ui::UiAction::Record(true) => {
                let file = format!("{}-{}.pfrec", self.scenario.name, unix_stamp());
                self.send(Control::Record(Some(PathBuf::from("recordings").join(file))));
            }
            ui::UiAction::Record(false) => self.send(Control::Record(None)),
            ui::UiAction::Seek(n) => self.send(Control::SeekStep(n)),
            ui::UiAction::ReplaySpeed(s) => self.send(Control::ReplaySpeed(s)),
            ui::UiAction::Pace(p) => self.send(Control::Pace(p)),
            ui::UiAction::TakeOver { branch } => {
                let path = branch.then(|| {
                    PathBuf::from("recordings").join(format!("{}-branch-{}.pfrec", self.scenario.name, unix_stamp()))
                });
                self.send(Control::TakeOver(path));
            }
        }
    }

    fn redraw(&mut self) -> Result<(), AppError> {
        let start = Instant::now();
        // The published set (never waits for the simulation).
        let (frames, front, info) = {
            let p = lock(&self.shared.published);
            (p.frames.clone(), p.front, p.info.clone())
        };
        let status = lock(&self.shared.status).clone();
        if let Some(fs) = &frames {
            if self.bind_groups.as_ref().is_none_or(|(gen_, _)| *gen_ != fs.generation) {
                let groups = [self.renderer.bind_frame(&fs.sets[0]), self.renderer.bind_frame(&fs.sets[1])];
                self.bind_groups = Some((fs.generation, groups));
            }
            if self.camera_fitted_for != fs.generation {
                self.camera = self.fit_camera();
                self.camera_fitted_for = fs.generation;
                let origin = info.origin;
                self.material_top = Some(self.compute_material_top(self.camera.up, origin));
            }
        }
        // egui
        let raw = self.egui_state.take_egui_input(&self.window);
        let mut settings = self.renderer.settings.clone();
        let mut actions = Vec::new();
        let stats = self.stats.clone();
        let ui_state = &mut self.ui;
        let full = self.egui_ctx.run_ui(raw, |ui| {
            actions = ui::panels(ui, ui_state, &status, &stats, &mut settings);
        });
        self.renderer.settings = settings;
        self.tools.speed_scale = self.ui.tool_speed;
        for a in actions {
            self.act(a);
        }
        self.egui_state.handle_platform_output(&self.window, full.platform_output);
        let ppp = full.pixels_per_point;
        let jobs = self.egui_ctx.tessellate(full.shapes, ppp);

        let frame = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(f) | wgpu::CurrentSurfaceTexture::Suboptimal(f) => f,
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                self.surface.configure(&self.ctx.device, &self.config);
                return Ok(());
            }
            _ => return Ok(()),
        };
        let view = frame.texture.create_view(&wgpu::TextureViewDescriptor::default());
        let scene_format = self.config.view_formats.first().copied().unwrap_or(self.config.format);
        let scene_view = frame
            .texture
            .create_view(&wgpu::TextureViewDescriptor { format: Some(scene_format), ..Default::default() });
        let size = (self.config.width, self.config.height);
        let mut enc =
            self.ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("viewer.frame") });
        let (dx_solid, dx_liquid) = snapshot::spacings(&self.scenario);
        let particles = match (&frames, &self.bind_groups) {
            (Some(fs), Some((_, groups))) => {
                Some((&groups[front], info.n_liquid.min(fs.sets[front].n_liquid), fs.sets[front].n_solid))
            }
            _ => None,
        };
        let scene = Scene { particles, objects: &info.objects, origin: info.origin, dx_solid, dx_liquid };
        self.renderer.draw(&mut enc, &scene_view, scene_format, size, &self.camera, &scene)?;
        // egui over the frame
        for (id, deltas) in &full.textures_delta.set {
            for delta in deltas {
                self.egui_renderer.update_texture(&self.ctx.device, &self.ctx.queue, *id, delta);
            }
        }
        let screen = egui_wgpu::ScreenDescriptor { size_in_pixels: [size.0, size.1], pixels_per_point: ppp };
        let extra = self.egui_renderer.update_buffers(&self.ctx.device, &self.ctx.queue, &mut enc, &jobs, &screen);
        {
            let pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("viewer.egui"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations { load: wgpu::LoadOp::Load, store: wgpu::StoreOp::Store },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            let mut pass = pass.forget_lifetime();
            self.egui_renderer.render(&mut pass, &jobs, &screen);
        }
        for id in &full.textures_delta.free {
            self.egui_renderer.free_texture(id);
        }
        self.ctx.queue.submit(extra.into_iter().chain([enc.finish()]));
        self.renderer.submitted();
        self.stats.gpu_pass_ms = self.renderer.pass_ms().iter().map(|(n, ms)| (n.to_string(), *ms)).collect();
        if let Some(path) = self.screenshot_next.take() {
            let msg = match self.save_screenshot(&frame.texture, &path) {
                Ok(()) => format!("saved {}", path.display()),
                Err(e) => format!("screenshot failed: {e}"),
            };
            log::info!("{msg}");
            self.ui.last_screenshot = Some(msg);
        }
        self.window.pre_present_notify();
        self.ctx.queue.present(frame);
        self.frames += 1;
        let now = Instant::now();
        let dt = now.duration_since(self.last_frame).as_secs_f64();
        self.last_frame = now;
        if dt > 0.0 {
            let fps = 1.0 / dt;
            self.stats.fps = if self.stats.fps == 0.0 { fps } else { 0.9 * self.stats.fps + 0.1 * fps };
        }
        self.stats.frame_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(())
    }

    /// Saves the window's frame (panels included) when the surface allows copies, else the 3-D view
    /// rendered offscreen at the window's size.
    fn save_screenshot(&mut self, texture: &wgpu::Texture, path: &std::path::Path) -> Result<(), AppError> {
        let err = |m: String| AppError::Screenshot { path: path.display().to_string(), message: m };
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| err(e.to_string()))?;
        }
        let size = (self.config.width, self.config.height);
        let img = if self.config.usage.contains(wgpu::TextureUsages::COPY_SRC) {
            let raw = crate::render::offscreen::read_texture(&self.ctx.device, &self.ctx.queue, texture, size, 4)
                .map_err(|e| err(e.to_string()))?;
            let mut raw = raw;
            if matches!(self.config.format, wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb) {
                for px in raw.chunks_exact_mut(4) {
                    px.swap(0, 2);
                }
            }
            for px in raw.chunks_exact_mut(4) {
                px[3] = 255;
            }
            image::RgbaImage::from_raw(size.0, size.1, raw).ok_or_else(|| err("bad pixel buffer".into()))?
        } else {
            return Err(err("the window surface does not allow copies on this adapter".into()));
        };
        img.save(path).map_err(|e| err(e.to_string()))
    }

    fn fit_camera(&self) -> OrbitCamera {
        let origin = lock(&self.shared.published).info.origin;
        let flat = self.scenario.dimensions == 2;
        let up = snapshot::up_axis(self.scenario.gravity);
        let (lo, hi) = snapshot::bounds(&snapshot::material_points(&self.scenario, origin)).unwrap_or((
            snapshot::to_sim(self.scenario.domain.min, origin),
            snapshot::to_sim(self.scenario.domain.max, origin),
        ));
        let pad = (hi - lo) * 0.3 + Vec3::splat(1e-3);
        OrbitCamera::fit(lo - pad, hi + pad, flat, up)
    }
}
