//! The egui panels of the viewer: scenario picker, run control, recording, tools, view settings,
//! live parameters, statistics, screenshot, keyboard help, the divergence banner and, in a replay,
//! the timeline (play/pause, speed, seek, take over). Panels only read
//! state and return [`UiAction`]s; `app` turns them into commands (data flows one way).

use super::sim_thread::SimStatus;
use crate::render::{FieldMode, RenderSettings};
use crate::scenario::ToolKind;
use std::path::PathBuf;

/// What the user asked for this frame.
#[derive(Clone, Debug, PartialEq)]
pub enum UiAction {
    Pause(bool),
    Step,
    Reset,
    Load(PathBuf),
    SelectTool(Option<ToolKind>),
    /// Gravity on/off and its scale (× the scenario's gravity).
    Gravity(bool),
    GravityScale(f64),
    Screenshot,
    ResetCamera,
    /// Start (true) or finish (false) recording the live session.
    Record(bool),
    /// Replay: go to step n.
    Seek(u64),
    /// Replay: playback speed (fraction of full speed).
    ReplaySpeed(f64),
    /// Live: cap on simulated seconds per wall second (`None`: as fast as it goes).
    Pace(Option<f64>),
    /// Replay: continue live from here, recording a branch when true.
    TakeOver {
        branch: bool,
    },
}

/// Render-thread statistics.
#[derive(Clone, Debug, Default)]
pub struct FrameStats {
    pub fps: f64,
    /// CPU time to build and submit the last frame \[ms\].
    pub frame_ms: f64,
    pub size: (u32, u32),
    pub adapter: String,
    /// GPU milliseconds per render pass (timestamp queries; empty where the adapter has none).
    pub gpu_pass_ms: Vec<(String, f64)>,
}

/// State the panels edit in place.
pub struct UiState {
    pub scenarios: Vec<PathBuf>,
    pub current: PathBuf,
    pub show_help: bool,
    pub gravity_on: bool,
    /// Gravity as a multiple of the scenario's (live parameter, 0 … 2).
    pub gravity_scale: f64,
    /// Tool speed as a fraction of the tool's maximum speed (live parameter, 0.05 … 1).
    pub tool_speed: f64,
    pub tools_available: Vec<ToolKind>,
    pub selected_tool: Option<ToolKind>,
    pub last_screenshot: Option<String>,
    /// Timeline position (step) while the user drags it (seek on release).
    pub scrub: Option<u64>,
    /// The loaded scenario's non-fatal notes (`scenario::warnings`), shown under the picker.
    pub scenario_warnings: Vec<String>,
}

/// Every shipped scenario (assets/scenarios/*.ron), sorted.
pub fn shipped_scenarios() -> Vec<PathBuf> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios");
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.extension().is_some_and(|x| x == "ron")).collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// The paces the run-control panel offers (simulated seconds per wall second; `None`: uncapped).
const PACES: [Option<f64>; 5] = [None, Some(1.0), Some(0.1), Some(0.01), Some(0.001)];

fn pace_label(p: Option<f64>) -> String {
    match p {
        None => "as fast as it goes".into(),
        Some(1.0) => "real time".into(),
        Some(r) => format!("{r}× real time"),
    }
}

/// The live run's pace: uncapped, real time, or slow motion for demonstrations (a fast GPU runs a
/// small scene faster than life; an instructor slows a hemorrhage down to watch it).
fn pace_picker(ui: &mut egui::Ui, current: Option<f64>, actions: &mut Vec<UiAction>) {
    ui.horizontal(|ui| {
        ui.label("pace");
        let mut chosen = current;
        egui::ComboBox::from_id_salt("pace")
            .selected_text(pace_label(current))
            .show_ui(ui, |ui| {
                for p in PACES {
                    ui.selectable_value(&mut chosen, p, pace_label(p));
                }
            })
            .response
            .on_hover_text("cap the simulated seconds per wall second (the real-time factor); not while relaxing");
        if chosen != current {
            actions.push(UiAction::Pace(chosen));
        }
    });
}

fn file_name(p: &std::path::Path) -> String {
    p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default()
}

/// Draws the panels; returns the actions.
pub fn panels(
    ui: &mut egui::Ui,
    state: &mut UiState,
    status: &SimStatus,
    frame: &FrameStats,
    render: &mut RenderSettings,
) -> Vec<UiAction> {
    let mut actions = Vec::new();
    if let Some(msg) = &status.diverged {
        egui::Panel::top("diverged").show(ui, |ui| {
            ui.colored_label(
                egui::Color32::from_rgb(255, 90, 80),
                format!("DIVERGED — paused with the last good state. {msg}. Reset (R) or load another scenario."),
            );
        });
    }
    if let Some(r) = &status.replay {
        timeline(ui, state, status, r, &mut actions);
        if let (true, Some(m)) = (r.at_end, &status.session) {
            egui::Window::new("Session summary").collapsible(true).default_pos([420.0, 60.0]).show(ui.ctx(), |ui| {
                session_grid(ui, m);
            });
        }
    }
    egui::Panel::left("controls").resizable(true).default_size(300.0).show(ui, |ui| {
        egui::ScrollArea::vertical().show(ui, |ui| {
            ui.heading("Perfuse");
            ui.label("Biphasic SPH: perfused tissue that deforms, tears and bleeds.");
            ui.separator();

            ui.strong("Scenario");
            let mut chosen = None;
            egui::ComboBox::from_id_salt("scenario").selected_text(file_name(&state.current)).show_ui(ui, |ui| {
                for p in &state.scenarios {
                    if ui.selectable_label(*p == state.current, file_name(p)).clicked() {
                        chosen = Some(p.clone());
                    }
                }
            });
            if let Some(p) = chosen {
                actions.push(UiAction::Load(p));
            }
            if !state.scenario_warnings.is_empty() {
                ui.colored_label(
                    egui::Color32::from_rgb(255, 170, 60),
                    format!("{} scenario warning(s)", state.scenario_warnings.len()),
                )
                .on_hover_text(state.scenario_warnings.join("\n"));
            }
            ui.horizontal(|ui| {
                let label = if status.paused { "Run" } else { "Pause" };
                if ui.button(label).on_hover_text("Space").clicked() {
                    actions.push(UiAction::Pause(!status.paused));
                }
                if ui.add_enabled(status.paused, egui::Button::new("Step")).on_hover_text("S").clicked() {
                    actions.push(UiAction::Step);
                }
                let reset = if status.replay.is_some() { "To start" } else { "Reset" };
                if ui.button(reset).on_hover_text("R: back to t = 0 (after the first relaxation: at once)").clicked() {
                    actions.push(UiAction::Reset);
                }
            });
            if status.replay.is_none() {
                pace_picker(ui, status.pace, &mut actions);
                ui.horizontal(|ui| match &status.recording {
                    Some((file, bytes)) => {
                        if ui.button("Stop recording").on_hover_text("V").clicked() {
                            actions.push(UiAction::Record(false));
                        }
                        ui.colored_label(
                            egui::Color32::from_rgb(230, 70, 60),
                            format!("REC {} ({:.1} MB)", file_name(std::path::Path::new(file)), *bytes as f64 / 1e6),
                        );
                    }
                    None => {
                        if ui.button("Record").on_hover_text("V: record the session to recordings/").clicked() {
                            actions.push(UiAction::Record(true));
                        }
                    }
                });
            }
            ui.separator();

            ui.strong("Tool");
            if state.tools_available.is_empty() {
                ui.label("This scenario has no tools.");
            }
            ui.horizontal_wrapped(|ui| {
                if ui.selectable_label(state.selected_tool.is_none(), "none (0)").clicked() {
                    actions.push(UiAction::SelectTool(None));
                }
                for (k, tool) in state.tools_available.iter().enumerate() {
                    let on = state.selected_tool == Some(*tool);
                    if ui.selectable_label(on, format!("{} ({})", tool.name(), k + 1)).clicked() {
                        actions.push(UiAction::SelectTool(Some(*tool)));
                    }
                }
            });
            ui.label("Left-drag: move the tool · Shift+wheel or Q/E: lower/raise · projectile: click to fire");
            ui.separator();

            ui.strong("View");
            let before = render.field;
            egui::ComboBox::from_id_salt("field").selected_text(render.field.name()).show_ui(ui, |ui| {
                for f in FieldMode::ALL {
                    ui.selectable_value(&mut render.field, f, f.name());
                }
            });
            if render.field != before {
                render.field_scale = render.field.default_scale();
            }
            if render.field != FieldMode::Plain {
                ui.add(egui::Slider::new(&mut render.field_scale, 1e-3..=1e5).logarithmic(true).text("full scale"));
            }
            ui.checkbox(&mut render.fluid, "blood as fluid surface (SSFR)");
            ui.checkbox(&mut render.show_walls, "walls and plates");
            ui.add(egui::Slider::new(&mut render.tissue_radius, 0.5..=2.0).text("tissue radius ×Δx/2"));
            ui.add(egui::Slider::new(&mut render.blood_radius, 0.5..=2.5).text("blood radius ×Δx/2"));
            ui.add(egui::Slider::new(&mut render.absorption, 10.0..=5000.0).logarithmic(true).text("absorption 1/m"));
            if ui.button("Reset camera").on_hover_text("C").clicked() {
                actions.push(UiAction::ResetCamera);
            }
            ui.separator();

            ui.strong("Live parameters");
            let mut g = state.gravity_on;
            if ui.checkbox(&mut g, "gravity").changed() {
                actions.push(UiAction::Gravity(g));
            }
            let mut scale = state.gravity_scale;
            let resp = ui.add_enabled(
                state.gravity_on && status.replay.is_none(),
                egui::Slider::new(&mut scale, 0.0..=2.0).text("gravity × scenario"),
            );
            if resp.changed() {
                actions.push(UiAction::GravityScale(scale));
            }
            ui.add(egui::Slider::new(&mut state.tool_speed, 0.05..=1.0).text("tool speed × max"))
                .on_hover_text("the speed a dragged tool follows the cursor at, and the projectile's speed");
            ui.separator();

            if let Some(v) = &status.vitals {
                ui.strong("Patient");
                egui::Grid::new("vitals").num_columns(2).show(ui, |ui| {
                    let row = |ui: &mut egui::Ui, k: &str, v: String| {
                        ui.label(k);
                        ui.label(v);
                        ui.end_row();
                    };
                    row(
                        ui,
                        "blood pressure",
                        format!("{:.0}/{:.0} mmHg (MAP {:.0})", v.systolic_mmhg, v.diastolic_mmhg, v.map_mmhg),
                    );
                    row(ui, "heart rate", format!("{:.0} bpm", v.hr_bpm));
                    row(ui, "cardiac output", format!("{:.2} L/min", v.cardiac_output_l_min));
                    row(
                        ui,
                        "blood lost",
                        format!("{:.0} mL ({:.1} %)", v.blood_lost_ml, 100.0 * v.blood_lost_fraction),
                    );
                    row(
                        ui,
                        "shock class (ATLS)",
                        ["–", "I", "II", "III", "IV"].get(v.shock_class as usize).unwrap_or(&"?").to_string(),
                    );
                    row(ui, "hepatic inflow", format!("{:.0} mL/min", v.hepatic_flow_ml_min));
                });
                vitals_plot(ui, &status.vitals_history);
                if let Some(m) = &status.session {
                    ui.strong("Session");
                    session_grid(ui, m);
                }
                ui.separator();
            }

            ui.strong("Statistics");
            egui::Grid::new("stats").num_columns(2).show(ui, |ui| {
                let row = |ui: &mut egui::Ui, k: &str, v: String| {
                    ui.label(k);
                    ui.label(v);
                    ui.end_row();
                };
                row(ui, "scenario", status.scenario.clone());
                row(ui, "back-end", status.backend.clone());
                row(ui, "particles", format!("{} solid + {} liquid", status.n_solid, status.n_liquid));
                row(ui, "sim time", format!("{:.5} s{}", status.t, if status.relaxing { " (relaxing)" } else { "" }));
                if let Some(f) = &status.relaxed_from {
                    ui.label("relaxation");
                    ui.label("kept from an earlier launch")
                        .on_hover_text(format!("{f}\n(`perfuse --fresh-relaxation` relaxes the organ again)"));
                    ui.end_row();
                }
                row(ui, "steps", status.steps.to_string());
                row(ui, "Δt", format!("{:.3e} s ({})", status.dt, status.dt_limit));
                row(ui, "steps/s", format!("{:.1}", status.steps_per_s));
                let cap = status.pace.map(|p| format!(" (pace {})", pace_label(Some(p)))).unwrap_or_default();
                row(ui, "real-time factor", format!("{:.2e}{cap}", status.real_time_factor));
                row(ui, "broken bonds", status.broken_bonds.to_string());
                row(ui, "render", format!("{:.1} fps, {:.1} ms/frame", frame.fps, frame.frame_ms));
                row(ui, "window", format!("{}×{}", frame.size.0, frame.size.1));
                row(ui, "adapter", frame.adapter.clone());
                for (name, ms) in &frame.gpu_pass_ms {
                    row(ui, &format!("  GPU {name}"), format!("{ms:.2} ms"));
                }
            });
            if let Some(e) = &status.error {
                ui.colored_label(egui::Color32::from_rgb(255, 170, 60), e);
            }
            ui.separator();
            ui.horizontal(|ui| {
                if ui.button("Screenshot").on_hover_text("P").clicked() {
                    actions.push(UiAction::Screenshot);
                }
                if ui.button("Help (H)").clicked() {
                    state.show_help = !state.show_help;
                }
            });
            if let Some(s) = &state.last_screenshot {
                ui.label(s);
            }
        });
    });
    if state.show_help {
        let mut open = true;
        egui::Window::new("Keyboard and mouse").open(&mut open).collapsible(false).show(ui.ctx(), |ui| {
            egui::Grid::new("help").num_columns(2).show(ui, |ui| {
                for (k, v) in HELP {
                    ui.monospace(*k);
                    ui.label(*v);
                    ui.end_row();
                }
            });
        });
        state.show_help = open;
    }
    actions
}

/// The session's metrics (issue 7 §4): what an instructor grades.
fn session_grid(ui: &mut egui::Ui, m: &crate::analysis::session::SessionReport) {
    let secs = |t: Option<f64>| t.map_or("–".to_string(), |t| format!("{t:.2} s"));
    egui::Grid::new(ui.next_auto_id()).num_columns(2).show(ui, |ui| {
        let mut row = |k: &str, v: String| {
            ui.label(k);
            ui.label(v);
            ui.end_row();
        };
        row("blood lost", format!("{:.1} mL", m.blood_lost_ml));
        row("loss rate", format!("{:.1} mL/min (peak {:.1})", m.loss_rate_ml_min, m.peak_loss_rate_ml_min));
        row("bonds broken", m.broken_bonds.to_string());
        row("first cut", secs(m.first_cut_s));
        let hemostasis = match (m.first_cut_s, m.bled, m.hemostasis_s) {
            (None, _, _) => "no cut yet".to_string(),
            (Some(_), false, _) => "no bleeding above the threshold".to_string(),
            (Some(_), true, None) => "bleeding".to_string(),
            (Some(_), true, Some(_)) => format!("after {}", secs(m.cut_to_hemostasis_s)),
        };
        row(&format!("hemostasis (≤ {} mL/min)", m.hemostasis_threshold_ml_min), hemostasis);
    });
}

/// The replay timeline: play/pause, back to the start, speed, a seek bar with the keyframes marked,
/// and take over (optionally recording a branch).
fn timeline(
    ui: &mut egui::Ui,
    state: &mut UiState,
    status: &SimStatus,
    r: &super::sim_thread::ReplayStatus,
    actions: &mut Vec<UiAction>,
) {
    egui::Panel::bottom("timeline").show(ui, |ui| {
        ui.horizontal(|ui| {
            ui.strong("Replay");
            ui.label(file_name(std::path::Path::new(&r.file)));
            if let Some(p) = &r.parent {
                ui.label(format!("(branch of {p})"));
            }
            if !r.warnings.is_empty() {
                ui.colored_label(egui::Color32::from_rgb(255, 170, 60), format!("{} warning(s)", r.warnings.len()))
                    .on_hover_text(r.warnings.join("\n"));
            }
        });
        ui.horizontal(|ui| {
            let label = if status.paused { "Play" } else { "Pause" };
            if ui.button(label).on_hover_text("Space").clicked() {
                actions.push(UiAction::Pause(!status.paused));
            }
            if ui.button("|<").on_hover_text("back to the start (R)").clicked() {
                actions.push(UiAction::Reset);
            }
            let mut speed = r.speed;
            egui::ComboBox::from_id_salt("speed").selected_text(format!("{speed}×")).width(60.0).show_ui(ui, |ui| {
                for s in [0.1, 0.25, 0.5, 1.0] {
                    ui.selectable_value(&mut speed, s, format!("{s}×"));
                }
            });
            if speed != r.speed {
                actions.push(UiAction::ReplaySpeed(speed));
            }
            let end = r.end_step.max(1);
            let mut n = state.scrub.unwrap_or(status.steps).min(end);
            ui.spacing_mut().slider_width = (ui.available_width() - 560.0).max(120.0);
            let resp = ui.add(egui::Slider::new(&mut n, 0..=end).text("step"));
            // keyframe ticks under the bar: seeking near one is fast
            let bar = resp.rect;
            let width = ui.spacing().slider_width;
            for k in &r.keyframes {
                let x = bar.left() + (*k as f32 / end as f32).clamp(0.0, 1.0) * width;
                ui.painter().line_segment(
                    [egui::pos2(x, bar.bottom() - 3.0), egui::pos2(x, bar.bottom())],
                    egui::Stroke::new(2.0, egui::Color32::from_rgb(90, 160, 255)),
                );
            }
            if resp.dragged() {
                state.scrub = Some(n);
            } else if resp.drag_stopped() || (resp.changed() && state.scrub.is_none()) {
                state.scrub = None;
                actions.push(UiAction::Seek(n));
            }
            ui.label(format!(
                "/ {} · t = {:.4} s{}{}",
                r.end_step,
                status.t,
                if status.relaxing || status.t < 0.0 { " (relaxation)" } else { "" },
                if r.at_end { " · end" } else { "" }
            ));
            if ui.button("Take over").on_hover_text("T: continue live from here with your own tool").clicked() {
                actions.push(UiAction::TakeOver { branch: false });
            }
            if ui
                .button("Take over + record")
                .on_hover_text("continue live from here, recording a branch that names this recording")
                .clicked()
            {
                actions.push(UiAction::TakeOver { branch: true });
            }
        });
    });
}

/// A small time plot of MAP (red) and HR (green) on a 40–160 scale, and blood lost (orange, 0 to the
/// largest loss).
fn vitals_plot(ui: &mut egui::Ui, history: &[[f64; 4]]) {
    let (rect, _) = ui.allocate_exact_size(egui::vec2(ui.available_width(), 70.0), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 2.0, egui::Color32::from_gray(24));
    let (Some(first), Some(last)) = (history.first(), history.last()) else { return };
    let span = (last[0] - first[0]).max(1e-9);
    let lost_max = history.iter().map(|h| h[3]).fold(1.0, f64::max);
    let x = |t: f64| rect.left() + ((t - first[0]) / span) as f32 * rect.width();
    let y = |v: f64, lo: f64, hi: f64| rect.bottom() - (((v - lo) / (hi - lo)).clamp(0.0, 1.0) as f32) * rect.height();
    for (k, colour, lo, hi) in [
        (1usize, egui::Color32::from_rgb(230, 70, 60), 40.0, 160.0),
        (2, egui::Color32::from_rgb(80, 200, 90), 40.0, 160.0),
        (3, egui::Color32::from_rgb(230, 150, 40), 0.0, lost_max),
    ] {
        let pts: Vec<egui::Pos2> = history.iter().map(|h| egui::pos2(x(h[0]), y(h[k], lo, hi))).collect();
        painter.add(egui::Shape::line(pts, egui::Stroke::new(1.5, colour)));
    }
    ui.label("red MAP, green HR (40–160), orange blood lost");
}

/// The controls, shown by the help overlay and the README.
pub const HELP: &[(&str, &str)] = &[
    ("Right-drag", "orbit the camera"),
    ("Middle-drag / Ctrl+right-drag", "pan"),
    ("Wheel", "zoom"),
    ("Left-drag", "move the selected tool (scalpel, indenter) on the working plane"),
    ("Shift+wheel, Q / E", "lower / raise the tool's working plane"),
    ("Left-click", "fire the projectile along the view ray (projectile selected)"),
    ("0 1 2 3", "no tool / select tool 1–3"),
    ("Space", "run / pause"),
    ("S", "single step (paused)"),
    ("R", "reset to the relaxed organ at t = 0, kept from the first relaxation (replay: to the start)"),
    ("V", "start / stop recording the session (recordings/)"),
    ("T", "replay: take over from here"),
    ("F", "cycle the tissue colour field"),
    ("B", "blood: fluid surface / spheres"),
    ("C", "reset the camera"),
    ("P", "screenshot (PNG)"),
    ("H", "this help"),
    ("Esc", "quit"),
];
