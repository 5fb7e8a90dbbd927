//! Offscreen rendering on the software adapter (issue 5 §5): a small scene drawn through the
//! viewer's renderer has blood pixels red where blood particles project, tissue where tissue is and
//! background elsewhere; the screen-space fluid passes are checked on a synthetic blob (the filtered
//! depth is smoother than the raw one, the thickness rises monotonically towards the blob's centre).
//! PNGs are saved under `target/test-artifacts/` for a person to look at.

mod common;

use common::gpu::gpu_test;
use glam::{Vec3, Vec4};
use perfuse::render::offscreen::read_texture;
use perfuse::render::{OrbitCamera, Renderer, snapshot};
use perfuse::scenario::Scenario;
use perfuse::sim::{BackendKind, Simulation};

/// A tissue block on the left, a blood ball on the right, a floor below and an indenter above.
const SCENE: &str = r#"
Scenario(
    name: "render_test",
    dimensions: 3,
    domain: Domain(min: (0.0, 0.0, 0.0), max: (0.012, 0.006, 0.007)),
    gravity: (0.0, 0.0, -9.81),
    liquid: Some(Liquid(density: 1000.0, viscosity: 0.01, sound_speed: Some(2.0))),
    solid: Some(Solid(density: 1000.0, c10: 1000.0, c01: 100.0, k_s: 10000.0, n_sat: 0.5, k_sat: 1000.0, friction: 10000.0)),
    numerics: Numerics(dx_liquid: Some(5.0e-4), dx_solid: Some(5.0e-4), h_over_dx: 1.3),
    particles: [
        Box(phase: Solid, min: (0.001, 0.001, 0.0015), max: (0.005, 0.005, 0.004), fraction: 0.6),
        Sphere(phase: Liquid, centre: (0.009, 0.003, 0.0035), radius: 0.002, fraction: 1.0),
    ],
    boundaries: [
        Boundary(name: "floor", shape: Box(min: (0.0, 0.0, 0.0), max: (0.012, 0.006, 0.0012))),
        Boundary(name: "tool", shape: Sphere(centre: (0.003, 0.003, 0.0058), radius: 0.0008),
                 tool: Some(Tool(kind: Indenter, max_speed: 0.1))),
    ],
    duration: 0.01,
)
"#;

fn artifact(name: &str) -> std::path::PathBuf {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/test-artifacts");
    std::fs::create_dir_all(&dir).expect("artifact dir");
    dir.join(name)
}

/// Pixel of a scenario-coordinate point.
fn project(cam: &OrbitCamera, size: (u32, u32), origin: [f64; 3], p: [f64; 3]) -> (u32, u32) {
    let q = Vec3::new((p[0] - origin[0]) as f32, (p[1] - origin[1]) as f32, (p[2] - origin[2]) as f32);
    let clip: Vec4 = cam.proj(size.0 as f32 / size.1 as f32) * cam.view() * q.extend(1.0);
    let (x, y) = (clip.x / clip.w, clip.y / clip.w);
    (((x + 1.0) * 0.5 * size.0 as f32) as u32, ((1.0 - y) * 0.5 * size.1 as f32) as u32)
}

#[test]
fn offscreen_frame_shows_blood_tissue_and_background() {
    gpu_test("offscreen_frame_shows_blood_tissue_and_background", |ctx| {
        let sc = Scenario::from_str_named(SCENE, "render_test.ron").expect("valid");
        let sim = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
        let mut renderer = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
        let size = (480, 270);
        let cam = OrbitCamera::fit(Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.012, 0.006, 0.007), false, Vec3::Z);
        let img = snapshot::render_image(&sim, &ctx, &mut renderer, &cam, size).expect("render");
        img.save(artifact("render_offscreen.png")).expect("png");
        let origin = sim.params().origin;
        let px = |p: [f64; 3]| {
            let (x, y) = project(&cam, size, origin, p);
            img.get_pixel(x.min(size.0 - 1), y.min(size.1 - 1)).0
        };
        // Blood: the ball's centre is red-dominant.
        let b = px([0.009, 0.003, 0.0035]);
        assert!(b[0] > 60 && b[0] as u32 > 3 * b[1] as u32 && b[0] as u32 > 3 * b[2] as u32, "blood pixel {b:?}");
        // Tissue: the block's front-top region is the liver's red-brown (red above green and blue, not
        // the blood's saturated red, not the background).
        let t = px([0.003, 0.001, 0.0035]);
        assert!(t[0] > t[1] && t[0] > t[2] && t[1] > 15, "tissue pixel {t:?}");
        // Background: a corner far from everything is exactly the clear colour.
        let bg = img.get_pixel(2, 2).0;
        let bg2 = img.get_pixel(size.0 - 3, 2).0;
        assert_eq!(bg, bg2, "background is uniform");
        assert!(bg[0] < 110 && bg[2] >= bg[0], "background {bg:?}");
        // Blood turned off: the same pixel shows plain spheres, still red.
        renderer.settings.fluid = false;
        let img2 = snapshot::render_image(&sim, &ctx, &mut renderer, &cam, size).expect("render");
        img2.save(artifact("render_offscreen_spheres.png")).expect("png");
        let (x, y) = project(&cam, size, origin, [0.009, 0.003, 0.0035]);
        let b2 = img2.get_pixel(x, y).0;
        assert!(b2[0] as u32 > 2 * b2[1] as u32, "sphere blood pixel {b2:?}");
    });
}

/// A moulded bed (`Boundary::mould`) is drawn as its particles, not as its box: the bed particle
/// nearest the camera shows the bed's pale pinkish grey, and a point inside the bed's box but beside
/// the tissue's footprint (no bed particle there) shows the background.
#[test]
fn a_moulded_bed_is_drawn_as_its_particles() {
    gpu_test("a_moulded_bed_is_drawn_as_its_particles", |ctx| {
        let sc = common::scenes::perfused_cube_under_gravity(
            "bed_render",
            r#"boundaries: [ Boundary(name: "bed", shape: Box(min: (-0.025, -0.025, -0.02), max: (0.025, 0.025, 0.01)),
                                   mould: Some(Mould(clearance: 0.004, depth: 0.008))) ],"#,
        );
        let sim = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
        let poses = sim.object_poses();
        let bed = &poses[0].bed;
        assert!(poses[0].moulded && !bed.is_empty(), "the bed's particles go with its pose");
        let mut renderer = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
        let size = (480, 360);
        let origin = sim.params().origin;
        let rel =
            |p: [f64; 3]| Vec3::new((p[0] - origin[0]) as f32, (p[1] - origin[1]) as f32, (p[2] - origin[2]) as f32);
        let cam = OrbitCamera::fit(rel([-0.025, -0.025, -0.02]), rel([0.025, 0.025, 0.02]), false, Vec3::Z);
        let img = snapshot::render_image(&sim, &ctx, &mut renderer, &cam, size).expect("render");
        img.save(artifact("render_moulded_bed.png")).expect("png");
        let px = |p: [f64; 3]| {
            let (x, y) = project(&cam, size, origin, p);
            img.get_pixel(x.min(size.0 - 1), y.min(size.1 - 1)).0
        };
        let eye = cam.eye();
        let nearest = bed
            .iter()
            .min_by(|a, b| (rel(**a) - eye).length().total_cmp(&(rel(**b) - eye).length()))
            .expect("a bed particle");
        let bg = img.get_pixel(2, 2).0;
        let b = px(*nearest);
        assert!(b != bg && b[0] > b[2] && b[0] > 40, "bed pixel {b:?} (background {bg:?})");
        // inside the bed's box, 2 cm beside the block: no particle there, and the box is not drawn
        let beside = px([0.022, -0.022, 0.0]);
        assert_eq!(beside, bg, "the bed's box is not drawn");
    });
}

/// A ball of blood alone, seen straight on.
const BLOB: &str = r#"
Scenario(
    name: "blob",
    dimensions: 3,
    domain: Domain(min: (0.0, 0.0, 0.0), max: (0.01, 0.01, 0.01)),
    liquid: Some(Liquid(density: 1000.0, viscosity: 0.01, sound_speed: Some(2.0))),
    numerics: Numerics(dx_liquid: Some(4.0e-4), h_over_dx: 1.3),
    particles: [ Sphere(phase: Liquid, centre: (0.005, 0.005, 0.005), radius: 0.0035, fraction: 1.0) ],
    duration: 0.01,
)
"#;

/// Σ|second difference| of a row of positive samples (roughness).
fn roughness(row: &[f32]) -> f32 {
    row.windows(3).map(|w| (w[0] - 2.0 * w[1] + w[2]).abs()).sum()
}

#[test]
fn ssfr_passes_on_a_synthetic_blob() {
    gpu_test("ssfr_passes_on_a_synthetic_blob", |ctx| {
        let sc = Scenario::from_str_named(BLOB, "blob.ron").expect("valid");
        let sim = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
        let mut renderer = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
        let size = (256, 256);
        let o = sim.params().origin;
        let c = Vec3::new((0.005 - o[0]) as f32, (0.005 - o[1]) as f32, (0.005 - o[2]) as f32);
        let cam = OrbitCamera { target: c, yaw: 0.0, pitch: 0.0, distance: 0.015, ..OrbitCamera::default() };
        let read = |r: &mut Renderer| -> (Vec<f32>, Vec<f32>, image::RgbaImage) {
            let img = snapshot::render_image(&sim, &ctx, r, &cam, size).expect("render");
            let (depth_tex, thick_tex) = r.fluid_textures().expect("targets exist");
            let d = read_texture(&ctx.device, &ctx.queue, depth_tex, size, 4).expect("depth");
            let t = read_texture(&ctx.device, &ctx.queue, thick_tex, size, 2).expect("thickness");
            let d: Vec<f32> = bytemuck::cast_slice::<u8, f32>(&d).to_vec();
            let t: Vec<f32> = t.chunks_exact(2).map(|b| half_to_f32(u16::from_le_bytes([b[0], b[1]]))).collect();
            (d, t, img)
        };
        let (filtered, thickness, img) = read(&mut renderer);
        img.save(artifact("ssfr_blob.png")).expect("png");
        renderer.settings.filter_radius_px = 0.0;
        let (raw, _, img_raw) = read(&mut renderer);
        img_raw.save(artifact("ssfr_blob_unfiltered.png")).expect("png");
        let w = size.0 as usize;
        let mid = size.1 as usize / 2;
        // The central third of the middle row is covered by blood in both.
        let span = (w / 3)..(2 * w / 3);
        let row = |v: &[f32]| v[mid * w..(mid + 1) * w][span.clone()].to_vec();
        let (rf, rr) = (row(&filtered), row(&raw));
        assert!(rf.iter().chain(rr.iter()).all(|d| *d > 0.0), "blob covers the middle");
        let (sf, sr) = (roughness(&rf), roughness(&rr));
        eprintln!("depth roughness: filtered {sf:.3e}, raw {sr:.3e}");
        assert!(sf < 0.5 * sr, "filtered depth must be smoother: {sf} vs {sr}");
        // Thickness: smoothed over ±3 px, it rises from the blob's edge to its centre.
        let tr = &thickness[mid * w..(mid + 1) * w];
        let first = tr.iter().position(|t| *t > 0.0).expect("thickness somewhere");
        let smooth: Vec<f32> = (first + 3..w / 2).map(|i| tr[i - 3..=i + 3].iter().sum::<f32>() / 7.0).collect();
        let drops = smooth.windows(2).filter(|p| p[1] < p[0] * 0.97).count();
        eprintln!("thickness edge {:.2e} → centre {:.2e} m, {} drops", smooth[0], tr[w / 2], drops);
        assert!(tr[w / 2] > 3.0 * smooth[0], "thicker at the centre than at the edge");
        assert!(drops <= smooth.len() / 10, "thickness rises towards the centre ({drops} drops)");
        // And the centre pixel is blood-red.
        let p = img.get_pixel(size.0 / 2, size.1 / 2).0;
        assert!(p[0] as u32 > 3 * p[1] as u32, "centre pixel {p:?}");
    });
}

/// IEEE half → f32 (R16Float texels).
fn half_to_f32(h: u16) -> f32 {
    let s = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let e = ((h >> 10) & 0x1f) as i32;
    let m = (h & 0x3ff) as f32;
    match e {
        0 => s * m * 2f32.powi(-24),
        31 => s * f32::INFINITY,
        _ => s * (1.0 + m / 1024.0) * 2f32.powi(e - 15),
    }
}

/// Runs `perfuse render` on [`SCENE`] at 64×48 on the CPU back-end with `args`, writing `png` into a
/// fresh artifact folder `dir_name`; asserts success and returns (folder, stdout), or None when
/// PERFUSE_SKIP_GPU_TESTS=1 (announced, as every GPU test does).
fn render_cli(test: &str, dir_name: &str, args: &[&str], png: &str) -> Option<(std::path::PathBuf, String)> {
    if std::env::var("PERFUSE_SKIP_GPU_TESTS").is_ok_and(|v| v == "1") {
        eprintln!("\n!!!!!!!! PERFUSE_SKIP_GPU_TESTS=1: SKIPPING `{test}` !!!!!!!!\n");
        return None;
    }
    let dir = artifact(dir_name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("dir");
    let scene = dir.join("scene.ron");
    std::fs::write(&scene, SCENE).expect("scene");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_perfuse"))
        .env("PERFUSE_CACHE_DIR", "") // no relaxed state kept in the user's cache by a test
        .arg("render")
        .arg(&scene)
        .args(["--backend", "cpu", "--size", "64x48"])
        .args(args)
        .arg("--out")
        .arg(dir.join(png))
        .output()
        .expect("run perfuse");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    Some((dir, stdout))
}

/// `perfuse render --every --until` writes a numbered PNG sequence from one simulation run (two
/// frames at a tiny size, so the test costs about a second on lavapipe).
#[test]
fn render_every_writes_a_numbered_png_sequence() {
    let Some((dir, stdout)) = render_cli(
        "render_every_writes_a_numbered_png_sequence",
        "render_sequence",
        &["--at", "0", "--every", "0.001", "--until", "0.001"],
        "seq.png",
    ) else {
        return;
    };
    for k in 0..2 {
        let img = image::open(dir.join(format!("seq_{k:05}.png"))).expect("frame is a PNG").to_rgba8();
        assert_eq!(img.dimensions(), (64, 48));
    }
    assert!(!dir.join("seq_00002.png").exists() && !dir.join("seq.png").exists());
    let times: Vec<f64> =
        stdout.lines().filter_map(|l| l.split("t = ").nth(1)?.split(' ').next()?.parse().ok()).collect();
    assert_eq!(times.len(), 2, "{stdout}");
    assert!(times[0] == 0.0 && times[1] >= 0.001, "{stdout}");
}

/// `perfuse render --timing N` prints the GPU milliseconds of every render pass (lavapipe has timestamp
/// queries) and the frame time: 64 frames at a tiny size, so two of them are timed.
#[test]
fn render_timing_prints_every_pass() {
    let Some((_, stdout)) =
        render_cli("render_timing_prints_every_pass", "render_timing", &["--timing", "64"], "timed.png")
    else {
        return;
    };
    assert!(stdout.contains("render timing at 64×48 over 64 frames"), "{stdout}");
    let ms = |name: &str| -> f64 {
        let line =
            stdout.lines().find(|l| l.trim_start().starts_with(name)).unwrap_or_else(|| panic!("{name}: {stdout}"));
        line.split_whitespace().rev().nth(1).and_then(|v| v.parse().ok()).unwrap_or_else(|| panic!("{line}"))
    };
    let frame = ms("frame (submit to GPU done)");
    assert!(frame.is_finite() && frame > 0.0, "{stdout}");
    if !stdout.contains("no timestamp queries") {
        for pass in ["scene", "blood thickness", "blood depth", "filter h", "filter v", "composite"] {
            let v = ms(pass);
            assert!(v.is_finite() && v >= 0.0, "{pass}: {stdout}");
        }
        assert!(ms("scene") > 0.0, "{stdout}");
    }
}

/// `perfuse render` shares the viewer's cache of relaxed states (`replay::relaxed_cache`): the first
/// render of a scenario with a relaxation keeps the relaxed state, the second starts from it (and
/// says so) and writes the same image byte for byte; `--fresh-relaxation` relaxes again, alike.
#[test]
fn render_reuses_the_kept_relaxed_state() {
    if std::env::var("PERFUSE_SKIP_GPU_TESTS").is_ok_and(|v| v == "1") {
        eprintln!("\n!!!!!!!! PERFUSE_SKIP_GPU_TESTS=1: SKIPPING `render_reuses_the_kept_relaxed_state` !!!!!!!!\n");
        return;
    }
    let dir = artifact("render_relaxed_cache");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("dir");
    let scene = dir.join("scene.ron");
    std::fs::write(&scene, SCENE).expect("scene");
    let render = |png: &str, fresh: bool| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_perfuse"))
            .env("PERFUSE_CACHE_DIR", dir.join("cache"))
            .arg("render")
            .arg(&scene)
            .args(["--backend", "cpu", "--size", "64x48", "--at", "2e-5"])
            .args(["--set", "relaxation=Some(Relaxation(duration: 4e-5, damping: 20.0, gravity_solid_only: true))"])
            .args(if fresh { &["--fresh-relaxation"][..] } else { &[] })
            .arg("--out")
            .arg(dir.join(png))
            .output()
            .expect("run perfuse");
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{stderr}");
        (std::fs::read(dir.join(png)).expect("png"), stderr)
    };
    let (first, e1) = render("first.png", false);
    assert!(!e1.contains("relaxed state from"), "nothing was kept yet: {e1}");
    let kept: Vec<_> = std::fs::read_dir(dir.join("cache")).expect("cache written").filter_map(Result::ok).collect();
    assert_eq!(kept.len(), 1, "one relaxed state kept");
    let (second, e2) = render("second.png", false);
    assert!(e2.contains("relaxed state from") && e2.contains("render_test-"), "{e2}");
    assert!(first == second, "the same image from the kept state");
    let (third, e3) = render("third.png", true);
    assert!(!e3.contains("relaxed state from"), "{e3}");
    assert!(first == third, "and from a fresh relaxation");
}
