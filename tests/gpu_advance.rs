//! Batched GPU stepping (`GpuSolver::advance`: up to 64 steps per submission, one readback, clock and
//! boundary motions on the GPU) against the CPU solver stepped one step at a time: a descending
//! (Translate) and an oscillating tool in the 3-D perfused block, and the periodic 2-D Poiseuille
//! channel; divergence inside a batch; determinism. Figures are printed (`--nocapture`).

mod common;

use common::gpu::gpu_test;
use common::scenes::{perfused_block, perfused_block_oscillating, poiseuille_small};
use glam::Vec3;
use perfuse::scenario::{Scenario, generate};
use perfuse::sim::cpu::CpuSolver;
use perfuse::sim::gpu::device::ErrorScope;
use perfuse::sim::gpu::{BatchTotals, GpuContext, GpuSolver};
use perfuse::sim::params::Params;
use perfuse::sim::{Command, SimError};

fn max_vec_diff(a: &[Vec3], b: &[Vec3]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| (*x - *y).length()).fold(0.0, f32::max)
}

fn solvers(ctx: GpuContext, sc: &Scenario, edit: impl Fn(&mut Params)) -> (CpuSolver, GpuSolver) {
    let g = generate(sc);
    let mut p = Params::new(sc, &g);
    edit(&mut p);
    let cpu = CpuSolver::new(p.clone(), &g).expect("CPU solver");
    let gpu = GpuSolver::from_cpu(ctx, &cpu).expect("GPU solver");
    (cpu, gpu)
}

/// `n` steps: GPU in batches (`advance`), CPU one by one; positions within 10⁻³ h (the whole-step
/// tolerance of gpu_vs_cpu.rs), clocks within 10⁻⁶ relative, same bonds and the same step count.
fn advance_matches(name: &str, sc: Scenario, n: u64) {
    gpu_test(name, |ctx| {
        let (mut cpu, mut gpu) = solvers(ctx, &sc, |_| {});
        let mut acc = BatchTotals::default();
        let t0 = std::time::Instant::now();
        gpu.advance(n, f64::INFINITY, &mut acc).expect("GPU advance");
        let gpu_secs = t0.elapsed().as_secs_f64();
        let (mut dt_min, mut dt_max) = (f32::INFINITY, 0.0f32);
        for _ in 0..n {
            let info = cpu.step().expect("CPU step");
            dt_min = dt_min.min(info.dt);
            dt_max = dt_max.max(info.dt);
        }
        let (g, c) = (gpu.read_state().expect("readback"), cpu.read_state());
        let h = cpu.params.k_liquid.h;
        let d_l = max_vec_diff(&g.liquid.pos, &c.liquid.pos);
        let d_s = max_vec_diff(&g.solid.pos, &c.solid.pos);
        let d_b = max_vec_diff(&g.boundary.pos, &c.boundary.pos);
        eprintln!(
            "{name}: {n} steps, t gpu {:.6e} cpu {:.6e}; max |Δx| liquid {:.3e} h, solid {:.3e} h, boundary {d_b:.3e} m; \
             dt gpu [{:.4e}, {:.4e}] cpu [{dt_min:.4e}, {dt_max:.4e}]; gpu {:.2} ms/step",
            g.t,
            c.t,
            d_l / h,
            d_s / h,
            acc.dt_min,
            acc.dt_max,
            1e3 * gpu_secs / n as f64
        );
        assert_eq!(acc.steps, n);
        assert_eq!(g.steps, c.steps);
        assert!((g.t - c.t).abs() <= 1e-6 * c.t);
        assert!(((acc.dt_min - dt_min) / dt_min).abs() <= 1e-5 && ((acc.dt_max - dt_max) / dt_max).abs() <= 1e-5);
        assert!(d_l <= 1e-3 * h && d_s <= 1e-3 * h, "positions diverged");
        assert!(d_b <= 1e-3 * h, "boundary poses diverged");
        assert_eq!(g.solid_extra.bond_lists, c.solid_extra.bond_lists);
    });
}

#[test]
fn advance_translate_tool_matches_cpu() {
    advance_matches("advance_translate_tool_matches_cpu", perfused_block(), 300);
}

#[test]
fn advance_oscillate_tool_matches_cpu() {
    advance_matches("advance_oscillate_tool_matches_cpu", perfused_block_oscillating(), 300);
}

#[test]
fn advance_periodic_2d_matches_cpu() {
    advance_matches("advance_periodic_2d_matches_cpu", poiseuille_small(), 300);
}

/// A scene without boundary objects (the shipped plane-strain beam, clamped by kinematic particles) binds
/// object and motion tables of one padded element: found by `validate --case cantilever --backend gpu`,
/// which wgpu refused ("bound with size 16 where the shader expects 80") before the padding.
#[test]
fn advance_without_boundary_objects_matches_cpu() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/cantilever_2d.ron");
    let sc = Scenario::load(&path).expect("cantilever_2d.ron");
    assert!(sc.boundaries.is_empty(), "the scene must have no boundary objects");
    advance_matches("advance_without_boundary_objects_matches_cpu", sc, 200);
}

/// `advance` stops at the first step whose end time reaches t_end, as a CPU loop `while t < t_end`.
#[test]
fn advance_stops_at_t_end_like_cpu() {
    gpu_test("advance_stops_at_t_end_like_cpu", |ctx| {
        let (mut cpu, mut gpu) = solvers(ctx, &perfused_block(), |_| {});
        let t_end = 1.0e-3;
        let mut acc = BatchTotals::default();
        gpu.advance(u64::MAX, t_end, &mut acc).unwrap();
        while cpu.st.t < t_end {
            cpu.step().unwrap();
        }
        eprintln!(
            "t_end {t_end:e}: gpu {} steps t = {:.6e}, cpu {} steps t = {:.6e}",
            gpu.steps(),
            gpu.time(),
            cpu.st.steps,
            cpu.st.t
        );
        assert_eq!(gpu.steps(), cpu.st.steps);
        assert!((gpu.time() - cpu.st.t).abs() <= 1e-6 * cpu.st.t);
    });
}

/// A run made to diverge (the runaway-speed limit lowered so the check trips after ~100 steps) reports
/// the same step from inside a 64-step GPU batch as the CPU, and keeps the last good state.
#[test]
fn diverging_batch_reports_cpu_step_and_keeps_last_good_state() {
    gpu_test("diverging_batch_reports_cpu_step_and_keeps_last_good_state", |ctx| {
        // Pick the limit halfway between the largest speed after 99 and after 100 steps (CPU).
        let sc = perfused_block();
        // strong sideways gravity (away from the floor, which stops what falls on it): the top
        // speed grows steadily, so the crossing step is clear-cut
        let gravity = Command::SetGravity([3000.0, 0.0, 0.0]);
        let mut probe = CpuSolver::new(Params::new(&sc, &generate(&sc)), &generate(&sc)).unwrap();
        probe.apply(&gravity).unwrap();
        let vmax = |s: &CpuSolver| s.st.liquid.v.iter().chain(&s.st.solid.v).map(|v| v.length()).fold(0.0f32, f32::max);
        let mut speeds = Vec::new();
        for _ in 0..140 {
            probe.step().unwrap();
            speeds.push(vmax(&probe));
        }
        // the step k ≥ 100 where the running maximum grows most (relatively): a clear crossing
        let mut run = speeds[..100].iter().copied().fold(0.0f32, f32::max);
        let mut pick = (0, 0.0f32, 0.0f32);
        for (k, v) in speeds.iter().enumerate().skip(100) {
            let jump = (*v - run) / run;
            if jump > pick.2 {
                pick = (k, 0.5 * (run + v), jump);
            }
            run = run.max(*v);
        }
        let (k, limit, jump) = pick;
        assert!(jump > 1e-4, "the top speed must grow after step 100 (jump {jump:e})");
        let (mut cpu, mut gpu) = solvers(ctx, &sc, |p| p.max_speed = limit);
        cpu.apply(&gravity).unwrap();
        gpu.apply(&gravity).unwrap();
        let cpu_err = loop {
            if let Err(e) = cpu.step() {
                break e;
            }
        };
        let mut acc = BatchTotals::default();
        let gpu_err = gpu.advance(300, f64::INFINITY, &mut acc).unwrap_err();
        eprintln!("limit {limit:.4e} m/s (step {}): cpu {cpu_err}\n gpu {gpu_err}", k + 1);
        let (SimError::Diverged { step: sc_, t: tc, .. }, SimError::Diverged { step: sg, t: tg, .. }) =
            (&cpu_err, &gpu_err)
        else {
            panic!("both must diverge: {cpu_err} / {gpu_err}");
        };
        assert_eq!(sc_, sg, "diverging step");
        assert!((tc - tg).abs() <= 1e-6 * tc);
        assert_eq!(acc.steps, sg - 1, "the good steps before the diverging one are counted");
        let (g, c) = (gpu.read_state().unwrap(), cpu.read_state());
        let h = cpu.params.k_liquid.h;
        assert_eq!(g.steps, c.steps);
        let d = max_vec_diff(&g.liquid.pos, &c.liquid.pos).max(max_vec_diff(&g.solid.pos, &c.solid.pos));
        eprintln!("last good state: {} steps, max |Δx| {:.3e} h", g.steps, d / h);
        assert!(d <= 1e-3 * h);
        // The kept state steps on (it is the last good one, not garbage).
        gpu.step().unwrap_err();
    });
}

/// Two batched runs give bit-identical states, and a batched run equals the same steps taken one by one.
#[test]
fn advance_is_deterministic_and_independent_of_batching() {
    gpu_test("advance_is_deterministic_and_independent_of_batching", |ctx| {
        let sc = perfused_block();
        let mut hashes = Vec::new();
        for batched in [true, true, false] {
            let (_, mut gpu) = solvers(ctx.clone(), &sc, |_| {});
            if batched {
                gpu.advance(150, f64::INFINITY, &mut BatchTotals::default()).unwrap();
            } else {
                for _ in 0..150 {
                    gpu.step().unwrap();
                }
            }
            hashes.push(gpu.read_state().unwrap().hash());
        }
        eprintln!("hashes {:016x} {:016x} {:016x}", hashes[0], hashes[1], hashes[2]);
        assert_eq!(hashes[0], hashes[1]);
        assert_eq!(hashes[0], hashes[2]);
    });
}

/// Evaluation 0 of every step but a batch's first after a host-side change reuses the liquid's ρ, nˡ,
/// nˢ, p and the solid's nˡ of the previous step's evaluation 1 (`liquid_density_fresh`,
/// `density_solid_kept`): after batches of a falling, deforming perfused block and after single steps
/// they are bit for bit what a fresh `density_liquid` / `density_solid` gives, and the state equals the
/// CPU's (which reuses them the same way) within the tolerances of `advance_matches`.
#[test]
fn reused_liquid_densities_equal_a_fresh_pass() {
    use perfuse::sim::gpu::bindings::Slot;
    use perfuse::sim::gpu::passes::{DENSITY_LIQUID, DENSITY_SOLID, Stage};
    gpu_test("reused_liquid_densities_equal_a_fresh_pass", |ctx| {
        let (mut cpu, mut gpu) = solvers(ctx, &perfused_block(), |_| {});
        let state = gpu.read_state().expect("state");
        let (n, ns) = (state.liquid.len(), state.solid.len());
        for (round, steps) in [(0, 40u64), (1, 1), (2, 25)] {
            if steps == 1 {
                gpu.step().expect("GPU step");
            } else {
                gpu.advance(steps, f64::INFINITY, &mut BatchTotals::default()).expect("GPU advance");
            }
            for _ in 0..steps {
                cpu.step().expect("CPU step");
            }
            assert!(gpu.reuses_liquid_density(), "round {round}: the next step would recompute them");
            let kept: Vec<[u32; 4]> = gpu.read_slot(Slot::LiquidDens, n).expect("read liquid_dens");
            let kept_s: Vec<[u32; 4]> = gpu.read_slot(Slot::SolidDens, ns).expect("read solid_dens");
            gpu.run_stages(&[Stage::Pass(DENSITY_SOLID)]).expect("fresh density_solid");
            let fresh_s: Vec<[u32; 4]> = gpu.read_slot(Slot::SolidDens, ns).expect("read solid_dens");
            let differ = kept_s.iter().zip(&fresh_s).filter(|(a, b)| a[1] != b[1]).count();
            assert_eq!(differ, 0, "round {round}: {differ} of {ns} solid particles' nˡ differ from a fresh pass");
            gpu.run_stages(&[Stage::Pass(DENSITY_LIQUID)]).expect("fresh density_liquid");
            let fresh: Vec<[u32; 4]> = gpu.read_slot(Slot::LiquidDens, n).expect("read liquid_dens");
            let differ = kept.iter().zip(&fresh).filter(|(a, b)| a != b).count();
            assert_eq!(
                differ, 0,
                "round {round}: {differ} of {n} liquid particles' (ρ, nˡ, nˢ, p) differ from a fresh pass"
            );
            assert!(!gpu.reuses_liquid_density(), "a host-side pass invalidates them");
        }
        let (g, c) = (gpu.read_state().expect("readback"), cpu.read_state());
        let h = cpu.params.k_liquid.h;
        assert!(g.liquid.vel.iter().any(|v| v.length() > 0.0), "the block moved");
        assert!(max_vec_diff(&g.liquid.pos, &c.liquid.pos) <= 1e-3 * h, "liquid positions diverged");
        assert!(max_vec_diff(&g.solid.pos, &c.solid.pos) <= 1e-3 * h, "solid positions diverged");
    });
}

/// Boundary objects that never move are neither re-placed nor re-binned between batches' steps: the
/// block with its tool held still, then a command that sets the tool moving (from then on every step
/// places and bins it again). The GPU in batches follows the CPU, stepped one by one, within the
/// tolerances of `advance_matches`, boundary poses included.
#[test]
fn fixed_boundaries_then_a_commanded_motion_match_cpu() {
    use perfuse::scenario::Motion;
    gpu_test("fixed_boundaries_then_a_commanded_motion_match_cpu", |ctx| {
        let text = common::scenes::PERFUSED_BLOCK_3D.replace("motion: Translate(velocity: (0.0, 0.0, -0.1))", "");
        let sc = Scenario::from_str_named(&text, "gpu_test_block_fixed.ron").expect("scene");
        let (mut cpu, mut gpu) = solvers(ctx, &sc, |_| {});
        let go = Command::SetBoundaryMotion {
            object: 1,
            motion: Motion::Translate { velocity: [0.0, 0.0, -0.1], start: 0.0, stop: None },
        };
        let b0 = cpu.read_state().boundary.pos;
        for (round, steps) in [(0, 60u64), (1, 60)] {
            if round == 1 {
                cpu.apply(&go).expect("CPU command");
                gpu.apply(&go).expect("GPU command");
            }
            gpu.advance(steps, f64::INFINITY, &mut BatchTotals::default()).expect("GPU advance");
            for _ in 0..steps {
                cpu.step().expect("CPU step");
            }
            let (g, c) = (gpu.read_state().expect("readback"), cpu.read_state());
            let h = cpu.params.k_liquid.h;
            let (d_l, d_s) = (max_vec_diff(&g.liquid.pos, &c.liquid.pos), max_vec_diff(&g.solid.pos, &c.solid.pos));
            let d_b = max_vec_diff(&g.boundary.pos, &c.boundary.pos);
            eprintln!(
                "round {round}: max |Δx| liquid {:.3e} h, solid {:.3e} h, boundary {d_b:.3e} m",
                d_l / h,
                d_s / h
            );
            assert!(d_l <= 1e-3 * h && d_s <= 1e-3 * h, "round {round}: positions diverged");
            assert!(d_b <= 1e-3 * h, "round {round}: boundary poses diverged");
            let moved = max_vec_diff(&c.boundary.pos, &b0);
            assert_eq!(moved > 0.0, round == 1, "round {round}: the tool moved {moved} m");
        }
    });
}

/// The CPU twin of batch.wgsl's motion evaluation agrees with `scenario::motion_at` (f64) to f32
/// rounding, including the t < 0 → rest rule, a Translate window and an Oscillate phase.
#[test]
fn motion_twin_matches_motion_at() {
    use perfuse::scenario::{Motion, motion_at};
    use perfuse::sim::gpu::{clock_pair, motion_entry, motion_twin};
    let sc = perfused_block();
    let g = generate(&sc);
    let params = Params::new(&sc, &g);
    let mut tool = g.objects[1].clone();
    let motions = [
        Motion::Translate { velocity: [0.01, -0.02, -0.1], start: 0.002, stop: Some(0.0075) },
        Motion::Translate { velocity: [0.0, 0.0, -0.1], start: 0.0, stop: None },
        Motion::Oscillate { amplitude: [0.0, 0.0005, -0.0006], frequency: 100.0, phase: 0.3 },
    ];
    let mut worst = 0.0f64;
    for m in motions {
        tool.motion = m.clone();
        let entry = motion_entry(&params, &tool);
        for k in -20..400 {
            let t = k as f64 * 2.5e-5 + 1.0e-7;
            let (d, v) = motion_at(&m, t);
            let (dg, vg) = motion_twin(&entry, clock_pair(t));
            let dd = (0..3).map(|a| (d[a] - dg[a] as f64).abs()).fold(0.0, f64::max);
            let dv = (0..3).map(|a| (v[a] - vg[a] as f64).abs()).fold(0.0, f64::max);
            // velocity scale: |velocity|, or ω·|amplitude|
            let amp = entry.vec.iter().map(|x| x.abs() as f64).fold(0.0, f64::max);
            let vmax = if entry.motion == 2 { amp * entry.times[0] as f64 } else { amp };
            // displacement to 1e-9 m (f32 of ~1e-3 m), velocity to 1e-5 of its scale
            assert!(dd <= 1e-9 && dv <= 1e-5 * vmax, "{m:?} at t = {t:e}: |Δd| {dd:e}, |Δv| {dv:e}");
            worst = worst.max(dd);
        }
    }
    eprintln!("motion twin vs motion_at: max |Δd| = {worst:.3e} m");
}

/// A shader that fails to parse is reported by the operation that created it, inside an enclosing
/// error scope too (the harness pushes one around every GPU test). Before `ErrorScope`, the solver
/// relied on the device's uncaptured-error handler, the harness's scope swallowed the parse error,
/// and the solver only failed later, when a batch ran no step.
#[test]
fn errors_reach_the_innermost_scope() {
    gpu_test("errors_reach_the_innermost_scope", |ctx| {
        let device = &ctx.device;
        let result = ErrorScope::around(device, "probe module", || {
            let _module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("perfuse.test.broken"),
                source: wgpu::ShaderSource::Wgsl("fn broken() -> u32 { return 1u +; }".into()),
            });
            Ok(())
        });
        let message = result.expect_err("a parse error must be reported").to_string();
        println!("{message}");
        assert!(message.contains("probe module"), "names the operation: {message}");
        // Nothing is left for the enclosing scope: a clean operation after it reports no error.
        ErrorScope::around(device, "clean", || Ok(())).expect("no error left over");
    });
}

/// `time_entry_points`: the timed batch (the second) reports one time per entry point that ran — the
/// step's own passes, evaluation 0's `forces_solid_xsph` and `density_solid_kept` among them — and
/// nothing else; back to families, the totals restart and are named by family.
#[test]
fn pass_times_per_entry_point() {
    use perfuse::sim::gpu::passes::ALL_PASSES;
    gpu_test("pass_times_per_entry_point", |ctx| {
        let (_, mut gpu) = solvers(ctx, &perfused_block(), |_| {});
        gpu.time_entry_points(true);
        let mut acc = BatchTotals::default();
        for _ in 0..2 {
            gpu.advance(3, f64::INFINITY, &mut acc).expect("GPU advance");
        }
        let Some(times) = gpu.pass_times() else {
            panic!("the software adapter has timestamp queries; no pass times came back");
        };
        let names: Vec<&str> = times.iter().map(|(k, _)| k.as_str()).collect();
        for (k, t) in &times {
            assert!(ALL_PASSES.iter().any(|p| p.entry == k), "{k} is not an entry point");
            assert!(t.is_finite() && *t >= 0.0, "{k}: {t}");
        }
        for want in ["forces_solid_xsph", "forces_solid", "density_solid_kept", "density_solid", "fracture_apply"] {
            let t = times.iter().find(|(k, _)| k == want).map(|(_, t)| *t);
            assert!(t.is_some_and(|t| t > 0.0), "{want} not timed: {names:?}");
        }
        assert!(!names.contains(&"forces"), "{names:?}");
        gpu.time_entry_points(false);
        for _ in 0..32 {
            gpu.advance(1, f64::INFINITY, &mut acc).expect("GPU advance");
        }
        let families: Vec<String> = gpu.pass_times().expect("pass times").into_iter().map(|(k, _)| k).collect();
        assert!(families.iter().any(|k| k == "forces") && families.iter().all(|k| k != "forces_solid"), "{families:?}");
    });
}
