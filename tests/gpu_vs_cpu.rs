//! Differential tests: the GPU back-end against its CPU twin on a small 3-D perfused block with a
//! wall and a moving tool (STYLE §5.5). Per pass: identical inputs (the GPU solver is loaded with the
//! CPU solver's state after a few steps), one GPU pass, readback, comparison with the twin under a
//! stated tolerance. Per step: both back-ends stepped N times from the same initial state.
//! Figures are printed (`--nocapture`) for the report.

mod common;

use common::gpu::gpu_test;
use common::scenes::{perfused_block, perfused_cube_under_gravity, sliding_block, wicking_block};
use glam::{Mat3, Vec3};
use perfuse::scenario::generate;
use perfuse::sim::cpu::{CpuSolver, Nbrs, ObjectContact, density, forces, ghosts, solid};
use perfuse::sim::gpu::bindings::Slot;
use perfuse::sim::gpu::gpu_types::CellEntry;
use perfuse::sim::gpu::passes::{self, Stage};
use perfuse::sim::gpu::{GpuContext, GpuSolver};
use perfuse::sim::params::Params;

fn cpu_solver() -> CpuSolver {
    solver_for(&perfused_block())
}

fn solver_for(sc: &perfuse::scenario::Scenario) -> CpuSolver {
    let g = generate(sc);
    CpuSolver::new(Params::new(sc, &g), &g).expect("CPU solver")
}

fn cpu_after(steps: usize) -> CpuSolver {
    stepped(cpu_solver(), steps)
}

fn stepped(mut cpu: CpuSolver, steps: usize) -> CpuSolver {
    for _ in 0..steps {
        cpu.step().expect("CPU step");
    }
    cpu
}

/// Steps both back-ends `n` times; their states after, and the largest position difference of the
/// liquid and the solid.
fn step_both(cpu: &mut CpuSolver, gpu: &mut GpuSolver, n: usize) -> (perfuse::sim::State, perfuse::sim::State, f32) {
    for _ in 0..n {
        gpu.step().expect("GPU step");
        cpu.step().expect("CPU step");
    }
    let (g, c) = (gpu.read_state().expect("GPU state"), cpu.read_state());
    let d_x = max_vec_diff(&g.liquid.pos, &c.liquid.pos).max(max_vec_diff(&g.solid.pos, &c.solid.pos));
    (g, c, d_x)
}

fn xyz(v: &[f32; 4]) -> Vec3 {
    Vec3::new(v[0], v[1], v[2])
}

fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max)
}

fn max_abs(a: &[f32]) -> f32 {
    a.iter().map(|x| x.abs()).fold(0.0, f32::max)
}

fn max_vec_diff(a: &[Vec3], b: &[Vec3]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| (*x - *y).length()).fold(0.0, f32::max)
}

fn bits3(a: &[Vec3]) -> Vec<[u32; 3]> {
    a.iter().map(|v| v.to_array().map(f32::to_bits)).collect()
}

fn max_len(a: &[Vec3]) -> f32 {
    a.iter().map(|x| x.length()).fold(0.0, f32::max)
}

fn nbrs(cpu: &CpuSolver) -> Nbrs<'_> {
    cpu.nbrs()
}

/// The CPU evaluation of `CpuSolver::evaluate`, pass by pass, on `cpu`'s state (its densities always
/// summed afresh, and evaluation 1's forces checked against evaluation 0's).
fn cpu_evaluate(cpu: &mut CpuSolver) {
    let (density::LiquidDensities { rho: rho_l, n_s: n_s_l, p: p_l, sees_ghost }, (n_l_s, n_s_s, p_s)) = {
        let nb = nbrs(cpu);
        let p = &cpu.params;
        (
            density::density_liquid(p, &p.outlets, &cpu.st.liquid, &cpu.st.solid, &cpu.st.boundary, &nb),
            density::density_solid(p, &cpu.st.solid, &cpu.st.liquid, &cpu.st.boundary, &nb, true),
        )
    };
    let l = &mut cpu.st.liquid;
    l.n_l = rho_l.iter().map(|r| r / cpu.params.rho0_l).collect();
    l.rho = rho_l;
    l.n_s = n_s_l;
    l.p = p_l;
    cpu.sees_ghost = sees_ghost;
    // the capsule's ghost sites' wall pressures and reactions (`ghosts::ghost_pressure`)
    if !cpu.ghosts.is_empty() {
        let nb = nbrs(cpu);
        let (p, st) = (&cpu.params, &cpu.st);
        let g = ghosts::ghost_pressure(p, &cpu.ghosts, &cpu.ghost_placed, &st.liquid, &st.solid, &nb.liquid);
        cpu.ghost_state = g;
    }
    let s = &mut cpu.st.solid;
    s.n_l = n_l_s;
    s.n_s = n_s_s;
    s.p = p_s;
    solid::solid_stress(&cpu.params, &mut cpu.st.solid);
    if cpu.params.hourglass > 0.0 {
        cpu.st.solid.hg_fit = solid::solid_fit(&cpu.params, &cpu.st.solid);
    }
    let (a_l, a_s, vx_l, vx_s, drho_s) = {
        let nb = nbrs(cpu);
        let ctx = force_ctx(cpu, &cpu.params, &cpu.contacts);
        let st = &cpu.st;
        let lf = forces::forces_liquid(&ctx, &st.liquid, &st.solid, &st.boundary, &nb, true);
        let (a_l, vx_l, seal) = (lf.a, lf.xsph, lf.seal_scale);
        let forces::SolidForces { a: a_s, xsph: vx_s, drho: drho_s } =
            forces::forces_solid(&ctx, &st.solid, &st.liquid, &st.boundary, &nb, true, &seal);
        // evaluation 1's passes (no XSPH) give the same accelerations bit for bit
        let lf1 = forces::forces_liquid(&ctx, &st.liquid, &st.solid, &st.boundary, &nb, false);
        let (a_l1, none_l) = (lf1.a, lf1.xsph);
        let forces::SolidForces { a: a_s1, xsph: none_s, drho: drho_s1 } =
            forces::forces_solid(&ctx, &st.solid, &st.liquid, &st.boundary, &nb, false, &seal);
        assert!(none_l.is_none() && none_s.is_none());
        assert!(bits3(&a_l1) == bits3(&a_l) && bits3(&a_s1) == bits3(&a_s), "forces differ with and without XSPH");
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert!(bits(&drho_s1) == bits(&drho_s), "dρ/dt differs with and without XSPH");
        (a_l, a_s, vx_l.expect("XSPH velocities"), vx_s.expect("XSPH velocities"), drho_s)
    };
    cpu.st.solid.drho = drho_s;
    cpu.st.liquid.a = a_l;
    cpu.st.solid.a = a_s;
    cpu.st.liquid.vx = vx_l;
    cpu.st.solid.vx = vx_s;
}

/// One evaluation of `cpu`'s state on a GPU solver built from it and on the CPU (`cpu_evaluate`): the
/// GPU's liquid and solid accelerations (the CPU's are left in `cpu`).
fn evaluate_both(ctx: GpuContext, cpu: &mut CpuSolver) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut gpu = gpu_from(ctx, cpu);
    gpu.run_stages(passes::EVALUATE).expect("GPU evaluation");
    cpu_evaluate(cpu);
    let al: Vec<[f32; 4]> = gpu.read_slot(Slot::LiquidAcc, cpu.st.liquid.x.len()).expect("liquid a");
    let as_: Vec<[f32; 4]> = gpu.read_slot(Slot::SolidAcc, cpu.st.solid.x.len()).expect("solid a");
    (al.iter().map(xyz).collect(), as_.iter().map(xyz).collect())
}

/// The force passes' context for `cpu`'s scene with parameters `p` and pressure modes `contacts`
/// (the liquid under gravity, `p`'s outlets in effect).
fn force_ctx<'a>(cpu: &'a CpuSolver, p: &'a Params, contacts: &'a [ObjectContact]) -> forces::ForceCtx<'a> {
    forces::ForceCtx {
        p,
        geoms: &cpu.geoms,
        gravity: cpu.st.gravity,
        contacts,
        gravity_liquid: true,
        outlets: &p.outlets,
        sees_ghost: &cpu.sees_ghost,
    }
}

fn gpu_from(ctx: GpuContext, cpu: &CpuSolver) -> GpuSolver {
    match GpuSolver::from_cpu(ctx, cpu) {
        Ok(g) => g,
        Err(e) => panic!("GPU solver: {e}"),
    }
}

/// Positions of one set as `[f32; 3]` (the CPU twin of the positions the cell entries carry).
fn positions(cpu: &CpuSolver, set: &str) -> Vec<[f32; 3]> {
    let p = match set {
        "liquid" => &cpu.st.liquid.x,
        "solid" => &cpu.st.solid.x,
        _ => &cpu.st.boundary.x,
    };
    p.iter().map(|v| v.to_array()).collect()
}

/// The GPU's cell lists (starts, ids, entry positions) equal the CPU's bit for bit.
fn assert_grids_match(cpu: &CpuSolver, gpu: &GpuSolver, when: &str) {
    let cells = cpu.params.grid.cell_count() + 1;
    for (name, list, order, start) in [
        ("liquid", &cpu.grids.liquid, Slot::LiquidOrder, Slot::LiquidCellStart),
        ("solid", &cpu.grids.solid, Slot::SolidOrder, Slot::SolidCellStart),
        ("boundary", &cpu.grids.boundary, Slot::BoundaryOrder, Slot::BoundaryCellStart),
    ] {
        let e: Vec<CellEntry> = gpu.read_slot(order, list.order.len()).expect("read cell entries");
        let s: Vec<u32> = gpu.read_slot(start, cells).expect("read cell starts");
        assert_eq!(s, list.cell_start, "{name} cell_start {when}");
        let o: Vec<u32> = e.iter().map(|e| e.id).collect();
        assert_eq!(o, list.order, "{name} order {when}");
        // each entry carries its particle's position, bit for bit
        let x = positions(cpu, name);
        for (q, e) in e.iter().enumerate() {
            let same = e.pos == x[e.id as usize] || (e.pos[0].is_nan() && x[e.id as usize][0].is_nan());
            assert!(same, "{name} entry {q} position {when}: {:?} vs {:?}", e.pos, x[e.id as usize]);
        }
    }
}

/// grid_count/scan/scatter/sort_cells: integer passes match bit for bit, at t = 0 and after 30 steps.
#[test]
fn grid_cell_lists_bit_identical() {
    gpu_test("grid_cell_lists_bit_identical", |ctx| {
        for steps in [0, 30] {
            let cpu = cpu_after(steps);
            let gpu = gpu_from(ctx.clone(), &cpu);
            assert_grids_match(&cpu, &gpu, &format!("after {steps} steps"));
        }
    });
}

/// Particles outside the domain (far beyond each face, one with a NaN coordinate) are clamped into
/// the border cells the same way on both back-ends (`cell_coords` ↔ `grid_cell_coords`).
#[test]
fn grid_bins_stray_particles_like_the_cpu() {
    gpu_test("grid_bins_stray_particles_like_the_cpu", |ctx| {
        let mut cpu = cpu_solver();
        let lo = cpu.params.grid.min;
        let strays = [
            Vec3::new(-1e30, 0.0, 1e30),
            Vec3::new(1e30, -1e30, 0.0),
            lo - Vec3::splat(0.5),
            Vec3::new(f32::NAN, lo.y + 1e-3, lo.z + 1e-3),
            Vec3::new(lo.x + 1e-3, f32::INFINITY, f32::NEG_INFINITY),
        ];
        for (k, x) in strays.iter().enumerate() {
            cpu.st.liquid.x[3 * k + 1] = *x;
            cpu.st.solid.x[5 * k + 2] = *x;
        }
        cpu.build_grids();
        // the three finite strays count as outside; a non-finite coordinate bins to cell 0 on its axis
        assert!(cpu.grids.liquid.outside >= 3, "{} liquid outside the grid", cpu.grids.liquid.outside);
        let gpu = gpu_from(ctx, &cpu);
        assert_grids_match(&cpu, &gpu, "with particles outside the domain");
    });
}

/// The three-phase prefix sum over more than 256 blocks of 64 cells (so each invocation of grid_scan_top
/// owns several blocks): the perfused block in a domain widened to over 16 384 cells.
#[test]
fn grid_cell_lists_bit_identical_on_a_large_grid() {
    gpu_test("grid_cell_lists_bit_identical_on_a_large_grid", |ctx| {
        let mut sc = perfused_block();
        for a in 0..3 {
            let (lo, hi) = (sc.domain.min[a], sc.domain.max[a]);
            let w = hi - lo;
            (sc.domain.min[a], sc.domain.max[a]) = (lo - w, hi + w);
        }
        let cpu = solver_for(&sc);
        let cells = cpu.params.grid.cell_count();
        assert!(cells > 64 * 256, "{cells} cells: the test needs more than 256 blocks of 64");
        let gpu = gpu_from(ctx, &cpu);
        for (name, list, start) in [
            ("liquid", &cpu.grids.liquid, Slot::LiquidCellStart),
            ("solid", &cpu.grids.solid, Slot::SolidCellStart),
            ("boundary", &cpu.grids.boundary, Slot::BoundaryCellStart),
        ] {
            let s: Vec<u32> = gpu.read_slot(start, cells + 1).unwrap();
            assert_eq!(s, list.cell_start, "{name} cell_start on {cells} cells");
        }
    });
}

/// density_liquid / density_solid (2.46), nˢ, nˡ (D-8) and penalty pressures (2.52), (2.53), and the
/// continuity (2.47), which forces_solid sums in its walks (so the whole evaluation runs).
/// Tolerances: ρ relative 1e-5 and dρ/dt 1e-4 of the largest value; n 1e-5 absolute; p 1e-6 of the
/// penalty stiffness (p = k(nˢ + nˡ − 1 …) cancels to a small difference of O(1) terms, so its absolute
/// error scales with k·ε_f32, and lavapipe may contract a·b + c into an FMA).
#[test]
fn density_passes_match_cpu() {
    gpu_test("density_passes_match_cpu", |ctx| {
        let mut cpu = cpu_after(40);
        let mut gpu = gpu_from(ctx, &cpu);
        gpu.run_stages(passes::EVALUATE).unwrap();
        cpu_evaluate(&mut cpu);
        let (l, s) = (&cpu.st.liquid, &cpu.st.solid);
        let ld: Vec<[f32; 4]> = gpu.read_slot(Slot::LiquidDens, l.x.len()).unwrap();
        let sd: Vec<[f32; 4]> = gpu.read_slot(Slot::SolidDens, s.x.len()).unwrap();
        let dr: Vec<[f32; 2]> = gpu.read_slot(Slot::SolidDrho, s.x.len()).unwrap();
        let col = |v: &[[f32; 4]], k: usize| v.iter().map(|x| x[k]).collect::<Vec<f32>>();
        let d_rho_l = max_abs_diff(&col(&ld, 0), &l.rho);
        let d_nl_l = max_abs_diff(&col(&ld, 1), &l.n_l);
        let d_ns_l = max_abs_diff(&col(&ld, 2), &l.n_s);
        let d_p_l = max_abs_diff(&col(&ld, 3), &l.p);
        let d_nl_s = max_abs_diff(&col(&sd, 1), &s.n_l);
        let d_ns_s = max_abs_diff(&col(&sd, 2), &s.n_s);
        let d_p_s = max_abs_diff(&col(&sd, 3), &s.p);
        let gdr: Vec<f32> = dr.iter().map(|x| x[0]).collect();
        let d_drho = max_abs_diff(&gdr, &s.drho);
        eprintln!(
            "density: liquid ρ {d_rho_l:.3e} (max {:.3e}), nˡ {d_nl_l:.3e}, nˢ {d_ns_l:.3e}, p {d_p_l:.3e} (max {:.3e}); \
             solid nˡ {d_nl_s:.3e}, nˢ {d_ns_s:.3e}, p {d_p_s:.3e} (max {:.3e}), dρ/dt {d_drho:.3e} (max {:.3e})",
            max_abs(&l.rho),
            max_abs(&l.p),
            max_abs(&s.p),
            max_abs(&s.drho)
        );
        assert!(d_rho_l <= 1e-5 * max_abs(&l.rho));
        assert!(d_nl_l <= 1e-5 && d_ns_l <= 1e-5 && d_nl_s <= 1e-5 && d_ns_s <= 1e-5);
        let p = &cpu.params;
        assert!(d_p_l <= 1e-6 * p.k_l.max(1.0));
        assert!(d_p_s <= 1e-6 * (p.k_s + p.k_sat).max(1.0));
        assert!(d_drho <= 1e-4 * max_abs(&s.drho).max(1e-6));
    });
}

/// `numerics.liquid_tension_below_ns` and `liquid_tension_in` on both back-ends (the syringe's free
/// blood and its needle's bore may take tension, the blood in tissue may not; README, `syringe.ron`):
/// the wicking block with the limit nˢ < 0.1, so that the free drop may go negative and the liquid in
/// the fabric (nˢ ≈ 0.3) may not — then with a box over half the block and a sphere as regions where the
/// fabric's liquid may go negative too. The liquid pressures agree as in `density_passes_match_cpu`
/// (1e-6 of the penalty stiffness), and on both back-ends no particle at nˢ ≥ 0.1 outside the region is
/// under tension while some below the limit are, and some in the region at nˢ ≥ 0.1 (and some outside
/// it would be without the clamp, (2.53) unclamped: the scene exercises both sides of the rule).
#[test]
fn tension_limit_matches_cpu() {
    use perfuse::scenario::Region;
    gpu_test("tension_limit_matches_cpu", |ctx| {
        let limit = 0.1f32;
        let regions = [
            None,
            Some(Region::Box { min: [-1.0, -1.0, -1.0], max: [0.003, 1.0, 1.0] }),
            Some(Region::Sphere { centre: [0.0, 0.0, 0.0031], radius: 0.004 }),
        ];
        for region in regions {
            let mut sc = wicking_block();
            sc.numerics.liquid_tension_below_ns = Some(f64::from(limit));
            sc.numerics.liquid_tension_in = region.clone().into_iter().collect();
            let mut cpu = stepped(solver_for(&sc), 20);
            let mut gpu = gpu_from(ctx.clone(), &cpu);
            gpu.run_stages(&[Stage::Pass(passes::DENSITY_LIQUID)]).unwrap();
            cpu_evaluate(&mut cpu);
            let (l, p) = (&cpu.st.liquid, &cpu.params);
            let ld: Vec<[f32; 4]> = gpu.read_slot(Slot::LiquidDens, l.x.len()).unwrap();
            let gpu_p: Vec<f32> = ld.iter().map(|x| x[3]).collect();
            let d_p = max_abs_diff(&gpu_p, &l.p);
            let count =
                |pr: &[f32], keep: &dyn Fn(usize) -> bool| (0..pr.len()).filter(|&i| keep(i) && pr[i] < 0.0).count();
            let raw: Vec<f32> =
                (0..l.x.len()).map(|i| p.k_l * (l.n_s[i] + l.n_l[i] - 1.0 + p.c1 * l.n_s[i] * l.n_l[i])).collect();
            let inside = |i: usize| p.liquid_tension_in.iter().any(|r| r.contains(l.x[i]));
            let above = |i: usize| l.n_s[i] >= limit && !inside(i);
            let above_in = |i: usize| l.n_s[i] >= limit && inside(i);
            let below = |i: usize| l.n_s[i] < limit;
            let (cpu_above, gpu_above, raw_above) = (count(&l.p, &above), count(&gpu_p, &above), count(&raw, &above));
            let (cpu_in, gpu_in) = (count(&l.p, &above_in), count(&gpu_p, &above_in));
            let (cpu_below, gpu_below) = (count(&l.p, &below), count(&gpu_p, &below));
            eprintln!(
                "tension limit nˢ < {limit}, region {region:?}: p GPU − CPU {d_p:.3e} (max {:.3e}); under tension at \
                 nˢ ≥ limit outside the region: CPU {cpu_above}, GPU {gpu_above} (unclamped {raw_above}); inside it: \
                 CPU {cpu_in}, GPU {gpu_in}; below the limit: CPU {cpu_below}, GPU {gpu_below} of {}",
                max_abs(&l.p),
                l.x.len()
            );
            assert!(d_p <= 1e-6 * p.k_l.max(1.0));
            assert!(raw_above > 0, "the scene must put liquid at nˢ ≥ {limit} under tension without the limit");
            assert_eq!((cpu_above, gpu_above), (0, 0), "tension where the liquid sees nˢ ≥ {limit} outside the region");
            assert!(cpu_below > 0 && gpu_below > 0, "the free liquid keeps its tension");
            if region.is_some() {
                assert!(cpu_in > 0 && gpu_in > 0, "the region's liquid at nˢ ≥ {limit} takes tension");
            } else {
                assert_eq!((cpu_in, gpu_in), (0, 0));
            }
        }
    });
}

/// solid_stress (τ, R), forces_liquid / forces_solid (2.48), (2.50) and XSPH (2.69) on the same
/// inputs. Tolerances: τ, R relative 1e-4 of their largest entry; accelerations 1e-4 of max |a|;
/// XSPH velocities 1e-5 of max |v| (plus 1e-9 m/s). Evaluation 0's passes, which also give the XSPH
/// velocities, give evaluation 1's accelerations bit for bit on both back-ends.
#[test]
fn stress_and_force_passes_match_cpu() {
    gpu_test("stress_and_force_passes_match_cpu", |ctx| {
        let mut cpu = cpu_after(40);
        let mut gpu = gpu_from(ctx, &cpu);
        gpu.run_stages(passes::EVALUATE).unwrap();
        let al1: Vec<[f32; 4]> = gpu.read_slot(Slot::LiquidAcc, cpu.st.liquid.x.len()).unwrap();
        let as1: Vec<[f32; 4]> = gpu.read_slot(Slot::SolidAcc, cpu.st.solid.x.len()).unwrap();
        gpu.run_stages(&[Stage::Pass(passes::FORCES_LIQUID_XSPH), Stage::Pass(passes::FORCES_SOLID_XSPH)]).unwrap();
        cpu_evaluate(&mut cpu);
        let (l, s) = (&cpu.st.liquid, &cpu.st.solid);
        let st: Vec<perfuse::sim::gpu::gpu_types::StressGpu> = gpu.read_slot(Slot::SolidStress, s.x.len()).unwrap();
        let mat_diff = |g: &dyn Fn(usize) -> Mat3, c: &[Mat3]| {
            let mut d = 0.0f32;
            let mut m = 0.0f32;
            for i in 0..c.len() {
                let (a, b) = (g(i).to_cols_array(), c[i].to_cols_array());
                for k in 0..9 {
                    d = d.max((a[k] - b[k]).abs());
                    m = m.max(b[k].abs());
                }
            }
            (d, m)
        };
        let (d_tau, m_tau) = mat_diff(&|i| st[i].tau(), &s.tau);
        let (d_art, m_art) = mat_diff(&|i| st[i].art(), &s.art);
        let al: Vec<[f32; 4]> = gpu.read_slot(Slot::LiquidAcc, l.x.len()).unwrap();
        let as_: Vec<[f32; 4]> = gpu.read_slot(Slot::SolidAcc, s.x.len()).unwrap();
        let vl: Vec<[f32; 4]> = gpu.read_slot(Slot::LiquidVelAdv, l.x.len()).unwrap();
        let vs: Vec<[f32; 4]> = gpu.read_slot(Slot::SolidVelAdv, s.x.len()).unwrap();
        let v3 = |v: &[[f32; 4]]| v.iter().map(xyz).collect::<Vec<Vec3>>();
        assert!(
            bits3(&v3(&al1)) == bits3(&v3(&al)) && bits3(&v3(&as1)) == bits3(&v3(&as_)),
            "GPU forces differ with XSPH"
        );
        let d_al = max_vec_diff(&v3(&al), &l.a);
        let d_as = max_vec_diff(&v3(&as_), &s.a);
        let d_vl = max_vec_diff(&v3(&vl), &l.vx);
        let d_vs = max_vec_diff(&v3(&vs), &s.vx);
        eprintln!(
            "stress: τ {d_tau:.3e} (max {m_tau:.3e}), R {d_art:.3e} (max {m_art:.3e}); forces: liquid a {d_al:.3e} (max {:.3e}), \
             solid a {d_as:.3e} (max {:.3e}); XSPH liquid {d_vl:.3e}, solid {d_vs:.3e} (max |v| {:.3e})",
            max_len(&l.a),
            max_len(&s.a),
            max_len(&s.v)
        );
        assert!(m_tau > 0.0, "test state must be stressed");
        assert!(d_tau <= 1e-4 * m_tau && d_art <= 1e-4 * m_art.max(1e-30));
        assert!(d_al <= 1e-4 * max_len(&l.a));
        assert!(d_as <= 1e-4 * max_len(&s.a));
        let vmax = max_len(&l.v).max(max_len(&s.v));
        assert!(d_vl <= 1e-5 * vmax + 1e-9 && d_vs <= 1e-5 * vmax + 1e-9);
    });
}

/// The hourglass control (`numerics.hourglass = 2`) on both back-ends: solid_fit's F̃ and the solid
/// accelerations with the pair force, on the test block after 40 steps (its tool has pressed and sheared
/// the tissue). Tolerances: F̃ entries 1e-5 (they are of order 1); solid a 1e-4 of max |a|; the control's
/// own share of max |a| is printed and must not vanish.
#[test]
fn hourglass_control_matches_cpu() {
    gpu_test("hourglass_control_matches_cpu", |ctx| {
        let sc = perfused_block().with_override("numerics.hourglass=2").expect("override");
        hourglass_matches(&ctx, &sc, "sheared block");
        // a capsule ten times stiffer than its tissue: its bonds are held by the pair's mean stiffness
        let sc = perfused_cube_under_gravity(
            "stiff_capsule_hourglass",
            "membrane: Some(Membrane(threshold: 0.5, count: 3, radius: 0.5, angle: 0.7853981633974483, stiffness: 10.0)),",
        )
        .with_override("numerics.hourglass=2")
        .expect("override");
        hourglass_matches(&ctx, &sc, "stiff capsule");
    });
}

/// One evaluation of `sc` after 40 CPU steps on both back-ends: F̃ and the solid accelerations agree,
/// and the control contributes to the latter.
fn hourglass_matches(ctx: &GpuContext, sc: &perfuse::scenario::Scenario, what: &str) {
    let mut cpu = stepped(solver_for(sc), 40);
    let mut gpu = gpu_from(ctx.clone(), &cpu);
    gpu.run_stages(passes::EVALUATE).expect("GPU evaluation");
    cpu_evaluate(&mut cpu);
    let n = cpu.st.solid.x.len();
    assert_eq!(cpu.st.solid.hg_fit.len(), n);
    let fit: Vec<perfuse::sim::gpu::gpu_types::Mat3Gpu> = gpu.read_slot(Slot::SolidAffine, n).expect("read F̃");
    let mut d_fit = 0.0f32;
    for (g, c) in fit.iter().zip(&cpu.st.solid.hg_fit) {
        for (x, y) in Mat3::from(*g).to_cols_array().iter().zip(c.to_cols_array()) {
            d_fit = d_fit.max((x - y).abs());
        }
    }
    let as_: Vec<[f32; 4]> = gpu.read_slot(Slot::SolidAcc, n).expect("read solid a");
    let g_a: Vec<Vec3> = as_.iter().map(xyz).collect();
    let a_on = cpu.st.solid.a.clone();
    let d_a = max_vec_diff(&g_a, &a_on);
    // the control's share: the same evaluation of the same state without it
    cpu.params.hourglass = 0.0;
    cpu_evaluate(&mut cpu);
    let share = max_vec_diff(&a_on, &cpu.st.solid.a);
    eprintln!(
        "hourglass, {what}: F̃ {d_fit:.3e}, solid a {d_a:.3e} (max {:.3e}; the control contributes up to {share:.3e})",
        max_len(&a_on)
    );
    assert!(share > 1e-3 * max_len(&a_on), "the control acts on the {what}");
    assert!(d_fit <= 1e-5, "F̃ differs by {d_fit}");
    assert!(d_a <= 1e-4 * max_len(&a_on));
}

/// One whole step from an identical state: F (solid_def_grad, 2.41–2.43), positions, velocities.
/// Tolerances: F entries 1e-5; positions 1e-6·h; velocities 1e-4 of max |v|.
#[test]
fn one_step_matches_cpu() {
    gpu_test("one_step_matches_cpu", |ctx| {
        let mut cpu = cpu_after(40);
        let mut gpu = gpu_from(ctx, &cpu);
        let ig = gpu.step().unwrap();
        let ic = cpu.step().unwrap();
        let (g, c) = (gpu.read_state().unwrap(), cpu.read_state());
        let mut d_f = 0.0f32;
        for (a, b) in g.solid_extra.def_grad.iter().zip(&c.solid_extra.def_grad) {
            for (x, y) in a.to_cols_array().iter().zip(b.to_cols_array()) {
                d_f = d_f.max((x - y).abs());
            }
        }
        let h = cpu.params.k_liquid.h;
        let d_x = max_vec_diff(&g.liquid.pos, &c.liquid.pos).max(max_vec_diff(&g.solid.pos, &c.solid.pos));
        let d_v = max_vec_diff(&g.liquid.vel, &c.liquid.vel).max(max_vec_diff(&g.solid.vel, &c.solid.vel));
        let vmax = max_len(&c.liquid.vel).max(max_len(&c.solid.vel));
        eprintln!(
            "one step: dt gpu {:.6e} cpu {:.6e} ({:?}/{:?}); F {d_f:.3e}; x {d_x:.3e} m ({:.3e} h); v {d_v:.3e} (max {vmax:.3e})",
            ig.dt,
            ic.dt,
            ig.limit,
            ic.limit,
            d_x / h
        );
        assert_eq!(ig.limit, ic.limit);
        assert!(((ig.dt - ic.dt) / ic.dt).abs() <= 1e-5);
        assert!(d_f <= 1e-5);
        assert!(d_x <= 1e-6 * h);
        assert!(d_v <= 1e-4 * vmax);
        assert_eq!(g.solid_extra.bond_lists, c.solid_extra.bond_lists);
    });
}

/// The perfused block with its liquid moving at random velocities (up to 0.1 m/s per axis, from `seed`)
/// and put in reversed storage order, then binned (`build_grids` renumbers it by cell when
/// `reorder_liquid`).
fn stirred_reversed_block(seed: u64, reorder_liquid: bool) -> CpuSolver {
    let mut cpu = cpu_solver();
    cpu.params.reorder_liquid = reorder_liquid;
    let mut seed = seed;
    let mut rnd = || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((seed >> 33) as f32 / (1u64 << 31) as f32) - 0.5
    };
    for v in cpu.st.liquid.v.iter_mut() {
        *v = Vec3::new(rnd(), rnd(), rnd()) * 0.2;
    }
    let reversed: Vec<u32> = (0..cpu.st.liquid.x.len() as u32).rev().collect();
    cpu.st.liquid.gather(&reversed);
    cpu.build_grids();
    cpu
}

/// grid_reorder_gather/apply ↔ grid::grid_reorder: a block whose liquid starts in reversed storage
/// order, moving at random velocities, is renumbered into its cell order by both back-ends the same
/// way (the GPU's id buffer equals the CPU's storage order of ids after every batch of 5 steps), and
/// the two stay together (positions by id within 1e-4·h after 20 steps).
#[test]
fn liquid_renumbering_matches_cpu() {
    gpu_test("liquid_renumbering_matches_cpu", |ctx| {
        let mut cpu = stirred_reversed_block(4242, true);
        let mut gpu = gpu_from(ctx, &cpu);
        let h = cpu.params.k_liquid.h;
        let nl = cpu.st.liquid.x.len();
        for round in 0..4 {
            let (g, c, d_x) = step_both(&mut cpu, &mut gpu, 5);
            let ids: Vec<u32> = gpu.read_slot(Slot::LiquidId, nl).expect("read liquid ids");
            eprintln!("after {} steps: max |Δx| {d_x:.3e} m ({:.3e} h)", 5 * (round + 1), d_x / h);
            assert_eq!(ids, cpu.st.liquid.id, "storage order of the liquid after {} steps", 5 * (round + 1));
            assert!(!ids.is_sorted(), "renumbered");
            assert_eq!(g.liquid.id, c.liquid.id, "both read back in id order");
            assert!(d_x <= 1e-4 * h, "positions diverged: {d_x:e} m");
        }
    });
}

/// With `numerics.reorder_liquid` off the liquid keeps its storage order and the GPU's liquid walks go
/// through the cell list's indirection (the pipeline constant `LIQUID_IN_CELL_ORDER` off, common.wgsl
/// `liquid_candidate`): a block whose liquid is stored in reversed order, moving at random velocities,
/// keeps that order on both back-ends and the two stay together (positions by id within 1e-4·h after
/// 20 steps) — the path the default, renumbered liquid no longer takes.
#[test]
fn liquid_walks_without_the_renumbering_match_cpu() {
    gpu_test("liquid_walks_without_the_renumbering_match_cpu", |ctx| {
        let mut cpu = stirred_reversed_block(1717, false);
        let stored = cpu.st.liquid.id.clone();
        let mut gpu = gpu_from(ctx, &cpu);
        let h = cpu.params.k_liquid.h;
        let nl = cpu.st.liquid.x.len();
        let (g, c, d_x) = step_both(&mut cpu, &mut gpu, 20);
        let ids: Vec<u32> = gpu.read_slot(Slot::LiquidId, nl).expect("read liquid ids");
        eprintln!("after 20 steps: max |Δx| {d_x:.3e} m ({:.3e} h)", d_x / h);
        assert_eq!(ids, stored, "the GPU kept the storage order");
        assert_eq!(cpu.st.liquid.id, stored, "the CPU kept the storage order");
        assert_eq!(g.liquid.id, c.liquid.id, "both read back in id order");
        assert!(c.liquid.vel.iter().any(|v| v.length() > 0.05), "the liquid moved");
        assert!(d_x <= 1e-4 * h, "positions diverged: {d_x:e} m");
    });
}

/// The whole step, 500 times from the same initial state: max position difference ≤ 1e-3·h.
#[test]
fn whole_step_500_matches_cpu() {
    gpu_test("whole_step_500_matches_cpu", |ctx| {
        let mut cpu = cpu_solver();
        let mut gpu = gpu_from(ctx, &cpu);
        let n = 500;
        let t0 = std::time::Instant::now();
        for _ in 0..n {
            gpu.step().unwrap();
        }
        let gpu_secs = t0.elapsed().as_secs_f64();
        let t0 = std::time::Instant::now();
        for _ in 0..n {
            cpu.step().unwrap();
        }
        let cpu_secs = t0.elapsed().as_secs_f64();
        let (g, c) = (gpu.read_state().unwrap(), cpu.read_state());
        let h = cpu.params.k_liquid.h;
        let d_l = max_vec_diff(&g.liquid.pos, &c.liquid.pos);
        let d_s = max_vec_diff(&g.solid.pos, &c.solid.pos);
        let d_b = max_vec_diff(&g.boundary.pos, &c.boundary.pos);
        let disp =
            c.solid.pos.iter().zip(&cpu_solver().st.solid.x).map(|(a, b)| (*a - *b).length()).fold(0.0, f32::max);
        eprintln!(
            "{n} steps (t = {:.4e} s gpu, {:.4e} s cpu): max |Δx| liquid {d_l:.3e} m ({:.3e} h), solid {d_s:.3e} m ({:.3e} h), \
             boundary {d_b:.3e}; max solid displacement {disp:.3e} m; {} particles; step time gpu {:.2} ms, cpu {:.2} ms",
            g.t,
            c.t,
            d_l / h,
            d_s / h,
            c.liquid.len() + c.solid.len(),
            1e3 * gpu_secs / n as f64,
            1e3 * cpu_secs / n as f64
        );
        assert!((g.t - c.t).abs() <= 1e-6 * c.t);
        assert!(d_l <= 1e-3 * h && d_s <= 1e-3 * h, "positions diverged");
        assert_eq!(g.solid_extra.bond_lists, c.solid_extra.bond_lists);
    });
}

/// The surface-tension terms (SPEC §3.12) on both back-ends: a drop on a plate under a fabric sheet
/// (half held, half free), with liquid–void attraction (3.4) and its reaction on the free fabric,
/// cohesion and adhesion (3.3), the wicking pressure (3.5) under tension and the liquid's artificial
/// pressure. Same tolerances as the force passes: accelerations within 1e-4 of max |a|; the
/// surface-tension terms and the artificial pressure are each checked to matter (their removal changes
/// the accelerations by far more than the tolerance).
#[test]
fn surface_tension_forces_match_cpu() {
    gpu_test("surface_tension_forces_match_cpu", |ctx| {
        let sc = wicking_block();
        let mut cpu = stepped(solver_for(&sc), 20);
        let (al, as_) = evaluate_both(ctx, &mut cpu);
        let (l, s) = (&cpu.st.liquid, &cpu.st.solid);
        let d_al = max_vec_diff(&al, &l.a);
        let d_as = max_vec_diff(&as_, &s.a);
        // The same state without the surface-tension terms: how much they contribute.
        let without = |f: &dyn Fn(&mut perfuse::sim::params::Params)| {
            let mut p = cpu.params.clone();
            f(&mut p);
            let nb = nbrs(&cpu);
            let ctx = force_ctx(&cpu, &p, &cpu.contacts);
            let lf = forces::forces_liquid(&ctx, &cpu.st.liquid, &cpu.st.solid, &cpu.st.boundary, &nb, false);
            let st = &cpu.st;
            (lf.a, forces::forces_solid(&ctx, &st.solid, &st.liquid, &st.boundary, &nb, false, &lf.seal_scale).a)
        };
        let (a_l0, a_s0) = without(&|p| {
            p.wicking = 0.0;
            p.cohesion_ll = 0.0;
            p.cohesion_lb = 0.0;
        });
        let st_l = max_vec_diff(&a_l0, &l.a);
        let st_s = max_vec_diff(&a_s0, &s.a);
        // The same state without the artificial pressure.
        let ap_l = max_vec_diff(&without(&|p| p.ap_eps = 0.0).0, &l.a);
        let tension = l.p.iter().filter(|&&p| p < 0.0).count();
        eprintln!(
            "surface tension: liquid a {d_al:.3e} (max {:.3e}, surface-tension part {st_l:.3e}, artificial-pressure \
             part {ap_l:.3e}, {tension} of {} liquid particles under tension), solid a {d_as:.3e} (max {:.3e}, part \
             {st_s:.3e})",
            max_len(&l.a),
            l.x.len(),
            max_len(&s.a)
        );
        assert!(st_l > 0.05 * max_len(&l.a), "the scene must exercise (3.3)/(3.4) on the liquid");
        assert!(ap_l > 1e-2 * max_len(&l.a), "the scene must exercise the liquid's artificial pressure");
        assert!(st_s > 1e-3 * max_len(&s.a), "the free fabric must feel the reaction of (3.4)");
        assert!(d_al <= 1e-4 * max_len(&l.a));
        assert!(d_as <= 1e-4 * max_len(&s.a));
    });
}

/// Coulomb wall contact (README: deviations from SPEC) on both back-ends: a block sliding on a plate
/// with μ = 0.5 under gravity tilted by 20°. The solid accelerations of one evaluation agree within
/// 1e-4 of max |a| — with the Coulomb terms shown to matter (the same state with SPEC §4.1 contact
/// differs by far more) — and 600 whole steps keep the positions within 1e-3 h.
#[test]
fn wall_friction_matches_cpu() {
    gpu_test("wall_friction_matches_cpu", |ctx| {
        let tilt = 20f64.to_radians();
        let sc = sliding_block(Some(0.5), 0.3, [9.81 * tilt.sin(), 0.0, -9.81 * tilt.cos()]);
        let mut cpu = stepped(solver_for(&sc), 100);
        let mut gpu = gpu_from(ctx.clone(), &cpu);
        gpu.run_stages(passes::EVALUATE).unwrap();
        cpu_evaluate(&mut cpu);
        let s = &cpu.st.solid;
        let as_: Vec<[f32; 4]> = gpu.read_slot(Slot::SolidAcc, s.x.len()).unwrap();
        let d_as = max_vec_diff(&as_.iter().map(xyz).collect::<Vec<Vec3>>(), &s.a);
        let spec_contact = {
            let contacts: Vec<_> = cpu.contacts.iter().map(|c| ObjectContact { friction: -1.0, ..*c }).collect();
            let nb = nbrs(&cpu);
            let ctx = force_ctx(&cpu, &cpu.params, &contacts);
            let st = &cpu.st;
            let seal = forces::forces_liquid(&ctx, &st.liquid, &st.solid, &st.boundary, &nb, false).seal_scale;
            forces::forces_solid(&ctx, &st.solid, &st.liquid, &st.boundary, &nb, false, &seal).a
        };
        let part = max_vec_diff(&spec_contact, &s.a);
        // The stick regime returns −v_t/Δt_up: velocity rounding (~1e-6 of max |v| after the
        // projection's cancellation) reaches the acceleration amplified by 1/Δt_up.
        let dt_up = cpu.params.dt_upper();
        let tol = 1e-4 * max_len(&s.a) + 1e-6 * max_len(&s.v) / dt_up;
        eprintln!(
            "wall friction: solid a {d_as:.3e} (tolerance {tol:.3e}: max |a| {:.3e}, max |v| {:.3e}, Δt_up {dt_up:.3e}); \
             Coulomb-contact part {part:.3e}",
            max_len(&s.a),
            max_len(&s.v)
        );
        assert!(part > 0.05 * max_len(&s.a), "the scene must exercise the Coulomb contact");
        assert!(d_as <= tol);
        let mut cpu = solver_for(&sc);
        let mut gpu = gpu_from(ctx, &cpu);
        for _ in 0..600 {
            gpu.step().unwrap();
            cpu.step().unwrap();
        }
        let (g, c) = (gpu.read_state().unwrap(), cpu.read_state());
        let h = cpu.params.k_solid.h;
        let d_s = max_vec_diff(&g.solid.pos, &c.solid.pos);
        let travel = c.solid.pos.iter().zip(&solver_for(&sc).st.solid.x).map(|(a, b)| a.x - b.x).sum::<f32>()
            / c.solid.len() as f32;
        eprintln!(
            "600 steps (t = {:.4e} s): max |Δx| solid {d_s:.3e} m ({:.3e} h); mean travel {travel:.3e} m",
            c.t,
            d_s / h
        );
        assert!(travel > 0.5 * h, "the block slid");
        assert!(d_s <= 1e-3 * h, "positions diverged");
    });
}

/// A perfused block resting on a bed moulded to its underside (`Boundary::mould`), whose box reaches
/// up through the block's lower half: both back-ends keep the block where it is (a moulded object has
/// no contact projection — with its box's, the lower half would be thrown out of it) and step alike.
#[test]
fn moulded_bed_matches_cpu() {
    gpu_test("moulded_bed_matches_cpu", |ctx| {
        let sc = perfused_cube_under_gravity(
            "bed",
            r#"boundaries: [ Boundary(name: "bed", shape: Box(min: (-0.02, -0.02, -0.02), max: (0.02, 0.02, 0.01)),
                                   mould: Some(Mould(clearance: 0.002, depth: 0.012))) ],"#,
        );
        let g = generate(&sc);
        // three layers under the block's 2 × 2 cm footprint (the bed's lattice, offset by half a
        // spacing from the block's, has 6 × 6 columns there, the outer ones under its faces at ±1 cm)
        assert_eq!(g.boundary_pos.len(), 3 * 36, "bed particles");
        assert!(
            g.boundary_pos.iter().all(|p| p[0].abs() <= 0.0101 && p[1].abs() <= 0.0101 && p[2] < 0.0),
            "beside the block"
        );
        let mut cpu = solver_for(&sc);
        let mut gpu = gpu_from(ctx, &cpu);
        let (gs, cs, d_x) = step_both(&mut cpu, &mut gpu, 300);
        let h = cpu.params.k_solid.h;
        let world_z = |s: &perfuse::sim::State| {
            s.solid.pos.iter().map(|x| cpu.params.to_world(*x)[2]).fold(f64::INFINITY, f64::min)
        };
        let (zg, zc) = (world_z(&gs), world_z(&cs));
        eprintln!(
            "moulded bed, 300 steps (t = {:.3e} s): max |Δx| {d_x:.3e} m ({:.3e} h); lowest solid z {zc:.4} (GPU {zg:.4}) m",
            cs.t,
            d_x / h
        );
        assert!(d_x <= 1e-3 * h, "positions diverged");
        // resting on the bed: inside the bed's box (no projection out of it), above the bed's top layer
        assert!((-0.002..0.01).contains(&zc) && (-0.002..0.01).contains(&zg), "lowest solid particle at {zc} / {zg} m");
    });
}

/// Elastic ligaments (`Scenario::ligaments`): a perfused block falls under gravity, held by damped
/// springs in a ball at its top. Both back-ends step alike (300 steps), and the tethered particles
/// stay nearer their anchors than the free ones below them.
#[test]
fn tethered_block_matches_cpu() {
    gpu_test("tethered_block_matches_cpu", |ctx| {
        let sc = perfused_cube_under_gravity(
            "tethered",
            "ligaments: Some(Ligaments(regions: [Sphere(centre: (0.0, 0.0, 0.02), radius: 0.009)], frequency: 30.0, damping_ratio: 0.5)),",
        );
        let mut cpu = solver_for(&sc);
        let tethered: Vec<bool> =
            cpu.st.solid.flags.iter().map(|f| f & perfuse::scenario::SolidFlags::TETHERED != 0).collect();
        let n_t = tethered.iter().filter(|&&t| t).count();
        assert!(n_t > 0 && n_t < tethered.len(), "{n_t} of {} tethered", tethered.len());
        let x0 = cpu.st.solid.x.clone();
        let mut gpu = gpu_from(ctx, &cpu);
        let (gs, cs, d_x) = step_both(&mut cpu, &mut gpu, 300);
        let h = cpu.params.k_solid.h;
        let d_v = max_vec_diff(&gs.solid.vel, &cs.solid.vel);
        let mean_drop = |s: &perfuse::sim::State, which: bool| {
            let ids: Vec<usize> = (0..x0.len()).filter(|&i| tethered[i] == which).collect();
            ids.iter().map(|&i| x0[i].z - s.solid.pos[i].z).sum::<f32>() / ids.len() as f32
        };
        let (drop_t, drop_f) = (mean_drop(&cs, true), mean_drop(&cs, false));
        eprintln!(
            "tethered block, 300 steps (t = {:.3e} s): max |Δx| {d_x:.3e} m ({:.3e} h), |Δv| {d_v:.3e} m/s; \
             mean drop: {n_t} tethered {drop_t:.3e} m, free {drop_f:.3e} m (GPU {:.3e} / {:.3e})",
            cs.t,
            d_x / h,
            mean_drop(&gs, true),
            mean_drop(&gs, false)
        );
        assert!(d_x <= 1e-3 * h, "positions diverged");
        assert!(drop_t > 0.0 && drop_f > drop_t, "the springs hold the top: drops {drop_t} / {drop_f} m");
    });
}

/// A capsule ten times stiffer than its tissue (`membrane.stiffness`), and the thesis's capsule (no
/// ghost sites: every capsule particle a boundary particle for all blood, SPEC §4.1): both back-ends
/// step the perfused cube with its capsule alike under gravity (300 steps), and the capsule's τ is the
/// stiffer.
#[test]
fn stiff_capsule_matches_cpu() {
    gpu_test("stiff_capsule_matches_cpu", |ctx| {
        let sc = perfused_cube_under_gravity(
            "stiff_capsule",
            "membrane: Some(Membrane(threshold: 0.5, count: 3, radius: 0.5, angle: 0.7853981633974483, stiffness: 10.0, \
             ghosts: false)),",
        );
        let mut cpu = solver_for(&sc);
        assert_eq!(cpu.params.membrane_stiffness, 10.0);
        assert!(!cpu.params.capsule_ghosts && cpu.ghosts.is_empty(), "the thesis's capsule");
        let mut gpu = gpu_from(ctx, &cpu);
        let (gs, cs, d_x) = step_both(&mut cpu, &mut gpu, 300);
        let h = cpu.params.k_solid.h;
        let d_f = gs
            .solid_extra
            .def_grad
            .iter()
            .zip(&cs.solid_extra.def_grad)
            .map(|(a, b)| (*a - *b).abs().to_cols_array().into_iter().fold(0.0f32, f32::max))
            .fold(0.0f32, f32::max);
        eprintln!(
            "stiff capsule, 300 steps (t = {:.3e} s): max |Δx| {d_x:.3e} m ({:.3e} h), |ΔF| {d_f:.3e}",
            cs.t,
            d_x / h
        );
        assert!(d_x <= 1e-3 * h, "positions diverged");
        assert!(d_f <= 1e-4, "deformation gradients diverged");
    });
}

/// The capsule's seal (`membrane.seal`, `forces::capsule_seal_pair`) on both back-ends: the perfused
/// cube under gravity after 50 CPU steps, its blood then given 5 cm/s outward from the cube's centre,
/// so that the blood in the seal's band beneath the capsule moves out through it. One evaluation: the
/// liquid and solid accelerations agree within 1e-4 of max |a| plus 1e-6 max |v| / Δt_max (the seal
/// divides a velocity by Δt_max, which amplifies the velocities' rounding, as wall friction's stick
/// does), and the seal matters: without it both sets' accelerations differ by far more, on the blood
/// and, through its reaction, on the capsule, whose forces and the blood's sum to zero. Evaluation 0's
/// advection velocities ṽ, which carry the seal's walk back to the capsule's plane, agree within 1e-5
/// of max |v|, and the walk matters.
#[test]
fn capsule_seal_matches_cpu() {
    gpu_test("capsule_seal_matches_cpu", |ctx| {
        const MEMBRANE: u32 = perfuse::scenario::SolidFlags::MEMBRANE;
        let sc = perfused_cube_under_gravity(
            "capsule_seal",
            "membrane: Some(Membrane(threshold: 0.5, count: 3, radius: 0.5, angle: 0.7853981633974483)),",
        );
        let mut cpu = stepped(solver_for(&sc), 50);
        assert_eq!(cpu.params.capsule_seal, 1.0, "membrane.seal is on by default");
        // the blood stretched about its centre, axis by axis, until its outer layers lie in the capsule's
        // faces (the seal's band), then moving outward
        let n = cpu.st.liquid.x.len() as f32;
        let centre = cpu.st.liquid.x.iter().fold(Vec3::ZERO, |a, x| a + *x) / n;
        let reach = |xs: &mut dyn Iterator<Item = Vec3>| xs.fold(Vec3::ZERO, |m, x| m.max((x - centre).abs()));
        let flags = &cpu.st.solid.flags;
        let capsule =
            reach(&mut cpu.st.solid.x.iter().zip(flags).filter(|(_, f)| **f & MEMBRANE != 0).map(|(x, _)| *x));
        let stretch = capsule / reach(&mut cpu.st.liquid.x.iter().copied());
        for (x, v) in cpu.st.liquid.x.iter_mut().zip(cpu.st.liquid.v.iter_mut()) {
            *x = centre + (*x - centre) * stretch;
            *v = (*x - centre).normalize_or_zero() * 0.05;
        }
        cpu.build_grids();
        let mut gpu = gpu_from(ctx, &cpu);
        gpu.run_stages(passes::EVALUATE).expect("GPU evaluation");
        let al: Vec<Vec3> =
            gpu.read_slot(Slot::LiquidAcc, cpu.st.liquid.x.len()).expect("liquid a").iter().map(xyz).collect();
        let as_: Vec<Vec3> =
            gpu.read_slot(Slot::SolidAcc, cpu.st.solid.x.len()).expect("solid a").iter().map(xyz).collect();
        gpu.run_stages(&[Stage::Pass(passes::FORCES_LIQUID_XSPH)]).expect("GPU evaluation 0");
        let vl: Vec<[f32; 4]> = gpu.read_slot(Slot::LiquidVelAdv, cpu.st.liquid.x.len()).expect("liquid ṽ");
        cpu_evaluate(&mut cpu);
        let (l, s) = (&cpu.st.liquid, &cpu.st.solid);
        let (d_al, d_as) = (max_vec_diff(&al, &l.a), max_vec_diff(&as_, &s.a));
        let vl: Vec<Vec3> = vl.iter().map(xyz).collect();
        let d_vx = max_vec_diff(&vl, &l.vx);
        let nb = nbrs(&cpu);
        let (without_l, without_s, without_vx) = {
            let mut p0 = cpu.params.clone();
            p0.capsule_seal = 0.0;
            let ctx = force_ctx(&cpu, &p0, &cpu.contacts);
            let st = &cpu.st;
            let lf = forces::forces_liquid(&ctx, &st.liquid, &st.solid, &st.boundary, &nb, true);
            let a_s = forces::forces_solid(&ctx, &st.solid, &st.liquid, &st.boundary, &nb, false, &lf.seal_scale).a;
            (lf.a, a_s, lf.xsph.expect("ṽ"))
        };
        // the walk back to the capsule's plane, in the blood's advection velocity ṽ alone
        let walked = l.vx.iter().zip(&without_vx).filter(|(a, b)| (**a - **b).length() > 0.0).count();
        let (part_vx, part_vx_gpu) = (max_vec_diff(&without_vx, &l.vx), max_vec_diff(&without_vx, &vl));
        let tol_vx = 1e-5 * max_len(&l.v) + 1e-9;
        let (part_l, part_s) = (max_vec_diff(&without_l, &l.a), max_vec_diff(&without_s, &s.a));
        let sealed = l.a.iter().zip(&without_l).filter(|(a, b)| (**a - **b).length() > 0.0).count();
        // the seal's forces on the blood and their reactions on the capsule sum to zero
        let (mut net, mut gross) = (Vec3::ZERO, 0.0f32);
        let forces_l = l.a.iter().zip(&without_l).zip(&l.m).map(|((a, b), m)| (*a - *b) * *m);
        for f in forces_l.chain(s.a.iter().zip(&without_s).zip(&s.m).map(|((a, b), m)| (*a - *b) * *m)) {
            net += f;
            gross += f.length();
        }
        let dt_up = cpu.params.dt_upper();
        let tol = |a: &[Vec3], v: &[Vec3]| 1e-4 * max_len(a) + 1e-6 * max_len(v) / dt_up;
        let (tol_l, tol_s) = (tol(&l.a, &l.v), tol(&s.a, &s.v.iter().chain(&l.v).copied().collect::<Vec<_>>()));
        eprintln!(
            "capsule seal: {sealed} of {} liquid sealed; liquid a {d_al:.3e} (tolerance {tol_l:.3e}, the seal's part \
             {part_l:.3e}), solid a {d_as:.3e} (tolerance {tol_s:.3e}, the seal's part {part_s:.3e}); net force \
             {:.3e} N of {gross:.3e} N",
            l.x.len(),
            net.length()
        );
        assert!(sealed > 0 && part_l > 100.0 * tol_l, "the scene must exercise the seal on the blood");
        assert!(part_s > 100.0 * tol_s, "the scene must exercise the seal's reaction on the capsule");
        assert!(net.length() <= 1e-4 * gross, "the seal's net force {net} (gross {gross})");
        assert!(d_al <= tol_l, "liquid accelerations differ by {d_al:e}");
        assert!(d_as <= tol_s, "solid accelerations differ by {d_as:e}");
        eprintln!(
            "capsule seal: {walked} walked back, ṽ {d_vx:.3e} (tolerance {tol_vx:.3e}, the walk {part_vx:.3e}, on the GPU {part_vx_gpu:.3e})"
        );
        assert!(walked > 0 && part_vx > 100.0 * tol_vx, "the scene must exercise the seal's walk back");
        assert!(d_vx <= tol_vx, "liquid advection velocities differ by {d_vx:e}");
        // the walk moves only blood that the mirror pressure does not hold (`capsule_seal_walks`, p ≤ 0):
        // the same blood under 100 Pa is left where it goes (ṽ as without the seal, bit for bit)
        let mut walked_p = l.vx.iter().zip(&without_vx).zip(&l.p).filter(|((a, b), _)| **a != **b);
        assert!(walked_p.all(|(_, p)| *p <= 0.0), "walked blood under pressure");
        let mut pressed = cpu.st.liquid.clone();
        pressed.p.iter_mut().for_each(|p| *p = 100.0);
        let ctx = force_ctx(&cpu, &cpu.params, &cpu.contacts);
        let st = &cpu.st;
        let vx_pressed = forces::forces_liquid(&ctx, &pressed, &st.solid, &st.boundary, &nb, true).xsph.expect("ṽ");
        assert!(vx_pressed == without_vx, "the seal walked blood under pressure");
    });
}

/// The capsule's ghost sites (`membrane.ghosts`, `sim::ghosts`) on both back-ends: the perfused cube
/// under gravity after 50 CPU steps. One evaluation: the liquid's ρ, nˢ and p agree within 1e-5 (p
/// within 1e-6 k), the same liquid sees a blood ghost, each ghost's wall pressure, density and
/// reaction agree within 1e-4 of their largest, and the accelerations within 1e-4 of max |a|; the
/// ghosts give the blood at the capsule the generated fractions where the capsule's layers did not, and their
/// forces on the blood and the reactions on the capsule sum to zero. Then 300 steps from the generated
/// state: positions within 1e-3 h.
#[test]
fn capsule_ghosts_match_cpu() {
    gpu_test("capsule_ghosts_match_cpu", |ctx| {
        let sc = perfused_cube_under_gravity(
            "capsule_ghosts",
            "membrane: Some(Membrane(threshold: 0.5, count: 3, radius: 0.5, angle: 0.7853981633974483, ghosts: true)),",
        );
        let fresh = solver_for(&sc);
        let n_ghosts = fresh.ghosts.len();
        let blood_ghosts = fresh.ghosts.m_l.iter().filter(|&&m| m > 0.0).count();
        assert!(fresh.params.capsule_ghosts && blood_ghosts > 0 && blood_ghosts < n_ghosts, "{n_ghosts} ghosts");
        assert!(fresh.ghosts.owner.is_sorted(), "ghosts sorted by owner");
        let mut cpu = stepped(fresh, 50);
        // the blood squeezed 3 % toward its centre (under pressure) and moving outward at up to ≈ 1 cm/s
        let n = cpu.st.liquid.x.len() as f32;
        let centre = cpu.st.liquid.x.iter().fold(Vec3::ZERO, |a, x| a + *x) / n;
        for (x, v) in cpu.st.liquid.x.iter_mut().zip(cpu.st.liquid.v.iter_mut()) {
            *x = centre + (*x - centre) * 0.97;
            *v += (*x - centre) * 1.0;
        }
        cpu.build_grids();
        let mut gpu = gpu_from(ctx.clone(), &cpu);
        gpu.run_stages(passes::EVALUATE).expect("GPU evaluation");
        let nl = cpu.st.liquid.x.len();
        let dens: Vec<[f32; 4]> = gpu.read_slot(Slot::LiquidDens, nl).expect("liquid densities");
        let sees: Vec<u32> = gpu.read_slot(Slot::LiquidSees, nl).expect("liquid sees");
        let gst: Vec<[f32; 4]> = gpu.read_slot(Slot::GhostState, 2 * n_ghosts).expect("ghost state");
        let al: Vec<Vec3> = gpu.read_slot(Slot::LiquidAcc, nl).expect("liquid a").iter().map(xyz).collect();
        let as_: Vec<Vec3> =
            gpu.read_slot(Slot::SolidAcc, cpu.st.solid.x.len()).expect("solid a").iter().map(xyz).collect();
        cpu.evaluate(false);
        let (l, s) = (&cpu.st.liquid, &cpu.st.solid);
        let col = |k: usize| dens.iter().map(|d| d[k]).collect::<Vec<f32>>();
        let (d_rho, d_ns, d_p) = (
            max_abs_diff(&col(0), &l.rho) / max_abs(&l.rho),
            max_abs_diff(&col(2), &l.n_s),
            max_abs_diff(&col(3), &l.p),
        );
        let seen: Vec<bool> = sees.iter().map(|&b| b != 0).collect();
        let n_seeing = cpu.sees_ghost.iter().filter(|&&b| b).count();
        let st = &cpu.ghost_state;
        let (gp, grho): (Vec<f32>, Vec<f32>) = (st.iter().map(|g| g.p).collect(), st.iter().map(|g| g.rho).collect());
        let react: Vec<Vec3> = st.iter().map(|g| g.reaction).collect();
        let gpu_p: Vec<f32> = (0..n_ghosts).map(|g| gst[2 * g][0]).collect();
        let gpu_rho: Vec<f32> = (0..n_ghosts).map(|g| gst[2 * g][1]).collect();
        let gpu_react: Vec<Vec3> = (0..n_ghosts).map(|g| xyz(&gst[2 * g + 1])).collect();
        let (d_gp, d_grho, d_react) =
            (max_abs_diff(&gpu_p, &gp), max_abs_diff(&gpu_rho, &grho), max_vec_diff(&gpu_react, &react));
        let (d_al, d_as) = (max_vec_diff(&al, &l.a), max_vec_diff(&as_, &s.a));
        // momentum: the ghosts' forces on the blood (its a less the a without them) against the reactions
        let without = {
            let no = Nbrs { ghosts: None, ..cpu.nbrs() };
            let ctx = force_ctx(&cpu, &cpu.params, &cpu.contacts);
            forces::forces_liquid(&ctx, &cpu.st.liquid, &cpu.st.solid, &cpu.st.boundary, &no, false).a
        };
        let on_blood = l.a.iter().zip(&without).zip(&l.m).fold(Vec3::ZERO, |f, ((a, b), m)| f + (*a - *b) * *m);
        let reactions = react.iter().fold(Vec3::ZERO, |f, r| f + *r);
        let gross: f32 = react.iter().map(|r| r.length()).sum();
        eprintln!(
            "capsule ghosts: {n_ghosts} ({blood_ghosts} blood), {n_seeing} of {nl} liquid see one; ρ {d_rho:.3e} rel, \
             nˢ {d_ns:.3e}, p {d_p:.3e} Pa; ghost p {d_gp:.3e} of {:.3e}, ρ {d_grho:.3e}, reaction {d_react:.3e} of \
             {:.3e} N; liquid a {d_al:.3e} of {:.3e}, solid a {d_as:.3e} of {:.3e}; ghost forces on the blood {:.3e} N, \
             reactions {:.3e} N (gross {gross:.3e})",
            max_abs(&gp),
            max_len(&react),
            max_len(&l.a),
            max_len(&s.a),
            on_blood.length(),
            reactions.length()
        );
        assert!(n_seeing > 0 && seen == cpu.sees_ghost, "the same liquid sees a blood ghost");
        assert!(d_rho <= 1e-5 && d_ns <= 1e-5 && d_p <= 1e-6 * cpu.params.k_l.max(1.0));
        assert!(max_abs(&gp) > 0.0 && gross > 0.0, "the scene must load the ghosts");
        assert!(d_gp <= 1e-4 * max_abs(&gp) && d_grho <= 1e-4 * max_abs(&grho));
        assert!(d_react <= 1e-4 * max_len(&react), "ghost reactions differ by {d_react:e}");
        assert!(d_al <= 1e-4 * max_len(&l.a), "liquid accelerations differ by {d_al:e}");
        assert!(d_as <= 1e-4 * max_len(&s.a), "solid accelerations differ by {d_as:e}");
        assert!((on_blood + reactions).length() <= 1e-4 * gross, "ghost forces and reactions do not cancel");
        // 300 steps from the generated state
        let mut cpu = solver_for(&sc);
        let mut gpu = gpu_from(ctx, &cpu);
        let (_, cs, d_x) = step_both(&mut cpu, &mut gpu, 300);
        let h = cpu.params.k_solid.h;
        eprintln!("capsule ghosts, 300 steps (t = {:.3e} s): max |Δx| {d_x:.3e} m ({:.3e} h)", cs.t, d_x / h);
        assert!(d_x <= 1e-3 * h, "positions diverged");
    });
}

/// The default scene whole (`liver.ron`: mesh, capsule ten times stiffer, elastic ligaments, moulded
/// bed, parked tools, blood under gravity), 30 steps from its generated state on both back-ends.
#[test]
fn default_liver_matches_cpu() {
    gpu_test("default_liver_matches_cpu", |ctx| {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/liver.ron");
        let sc = perfuse::scenario::Scenario::load_with_overrides(&path, &[]).expect("liver.ron is valid");
        let mut cpu = solver_for(&sc);
        let flags = &cpu.st.solid.flags;
        let count = |bit: u32| flags.iter().filter(|&&f| f & bit != 0).count();
        let (tethered, membrane) =
            (count(perfuse::scenario::SolidFlags::TETHERED), count(perfuse::scenario::SolidFlags::MEMBRANE));
        assert!(
            tethered > 0 && membrane > 0 && cpu.params.membrane_stiffness > 1.0,
            "the scene exercises its features"
        );
        let mut gpu = gpu_from(ctx, &cpu);
        let (gs, cs, d_x) = step_both(&mut cpu, &mut gpu, 30);
        let h = cpu.params.k_solid.h;
        let d_v = max_vec_diff(&gs.solid.vel, &cs.solid.vel).max(max_vec_diff(&gs.liquid.vel, &cs.liquid.vel));
        eprintln!(
            "default liver ({} solid: {tethered} tethered, {membrane} capsule; {} liquid), 30 steps (t = {:.3e} s): \
             max |Δx| {d_x:.3e} m ({:.3e} h), |Δv| {d_v:.3e} m/s; broken {} / {}",
            cs.solid.len(),
            cs.liquid.len(),
            cs.t,
            d_x / h,
            gs.broken_bonds(),
            cs.broken_bonds()
        );
        assert!(d_x <= 1e-3 * h, "positions diverged");
        assert_eq!(gs.broken_bonds(), cs.broken_bonds(), "broken bonds");
    });
}

/// How far the deepest particle of `x` lies inside a moulded bed's surface (`sim::bed`), over the beds
/// of `cpu`'s scene.
fn deepest_in_bed(cpu: &CpuSolver, x: &[Vec3]) -> f32 {
    let t = &cpu.beds;
    let three_d = cpu.params.dim.n() == 3;
    let mut deepest = 0.0f32;
    for &off in t.offsets.iter().filter(|o| **o > 0) {
        for p in x {
            if let Some((y, _)) = perfuse::sim::bed::bed_contact(&t.data, off as usize - 1, *p, three_d) {
                deepest = deepest.max((y - *p).length());
            }
        }
    }
    deepest
}

/// A perfused block thrown at 1.5 m/s onto the bed moulded under it: the bed's surface (its lattice
/// columns' tops) stops tissue and blood on both back-ends alike, where the bed's particles alone
/// (the same scene with the surface removed) let them in.
#[test]
fn a_moulded_bed_stops_what_is_thrown_at_it() {
    gpu_test("a_moulded_bed_stops_what_is_thrown_at_it", |ctx| {
        let text = r#"Scenario(
            name: "gpu_test_bed", dimensions: 3,
            domain: Domain(min: (0.0, 0.0, 0.0), max: (0.006, 0.006, 0.006)),
            gravity: (0.0, 0.0, -9.81),
            liquid: Some(Liquid(density: 1000.0, viscosity: 0.01, sound_speed: Some(2.0))),
            solid: Some(Solid(density: 1000.0, c10: 1000.0, c01: 100.0, k_s: 10000.0, n_sat: 0.5,
                              k_sat: 1000.0, friction: 10000.0)),
            numerics: Numerics(dx_liquid: Some(5.0e-4), dx_solid: Some(5.0e-4), h_over_dx: 1.3),
            particles: [
                Box(phase: Solid, min: (0.0015, 0.0015, 0.002), max: (0.0045, 0.0045, 0.0035), fraction: 0.5,
                    velocity: Some(Uniform((0.0, 0.0, -1.5)))),
                Box(phase: Liquid, min: (0.0015, 0.0015, 0.002), max: (0.0045, 0.0045, 0.0035), fraction: 0.5,
                    velocity: Some(Uniform((0.0, 0.0, -1.5)))),
            ],
            boundaries: [ Boundary(name: "bed", shape: Box(min: (0.0, 0.0, 0.0), max: (0.006, 0.006, 0.002)),
                                   mould: Some(Mould(clearance: 5.0e-4, depth: 1.5e-3))) ],
            duration: 0.01,
        )"#;
        let sc = perfuse::scenario::Scenario::from_str_named(text, "gpu_test_bed.ron").expect("test scene is valid");
        let mut cpu = solver_for(&sc);
        assert!(cpu.beds.offsets == [1], "the bed has a surface");
        let mut bare = solver_for(&sc);
        bare.beds = perfuse::sim::bed::BedTable::default();
        let mut gpu = gpu_from(ctx, &cpu);
        let steps = 150;
        let (gs, cs, d_x) = step_both(&mut cpu, &mut gpu, steps);
        let bs = stepped(bare, steps).read_state();
        let h = cpu.params.k_solid.h;
        let all = |s: &perfuse::sim::State| s.solid.pos.iter().chain(&s.liquid.pos).copied().collect::<Vec<_>>();
        let (deep_c, deep_g, deep_b) =
            (deepest_in_bed(&cpu, &all(&cs)), deepest_in_bed(&cpu, &all(&gs)), deepest_in_bed(&cpu, &all(&bs)));
        eprintln!(
            "block thrown onto its bed, {steps} steps (t = {:.3e} s): deepest inside the surface cpu {deep_c:.2e} m, \
             gpu {deep_g:.2e}, without the surface {deep_b:.2e} ({:.2} Δx); max |Δx| gpu–cpu {d_x:.3e} m ({:.3e} h)",
            cs.t,
            deep_b / 5e-4,
            d_x / h
        );
        assert!(deep_b > 0.2 * 5e-4, "the throw does not reach into the bed: the test checks nothing");
        assert!(deep_c <= 1e-6 && deep_g <= 1e-6, "particles inside the bed");
        assert!(d_x <= 1e-3 * h, "positions diverged");
    });
}

/// A vessel of boxes — `docs/sealed_column.ron` without tension: a floor, four side walls standing on
/// it and meeting at the corners, a −5 kPa disc with a sink under it on top — holds its liquid on both
/// back-ends: at 0.04 s no particle is outside the tube's inside (10 × 10 mm, above the floor; within
/// 10⁻⁶ m for f32 rounding of the faces). Before `object_contact` put particles on the boxes' union
/// (`box_exit`), the nearest face of a wall's foot was the plane it shares with the floor: on the CPU 4
/// particles had slid out along the seams by 0.03 s and 12 by 0.04 s (README: `syringe.ron` under
/// Validation). Both back-ends also sink the same number of particles.
#[test]
fn a_vessel_of_boxes_holds_its_liquid_on_both_back_ends() {
    use perfuse::sim::{BackendKind, Simulation};
    let sc = perfuse::scenario::Scenario::from_str_with_overrides(
        include_str!("../docs/sealed_column.ron"),
        "docs/sealed_column.ron",
        &["numerics.liquid_tension=false".to_string()],
    )
    .expect("the probe scenario");
    let run = |backend: BackendKind| {
        let mut sim = Simulation::new(&sc, backend).expect("sim");
        sim.advance_until(0.04, u64::MAX, |_| {}).expect("run");
        let st = sim.read_state().expect("state");
        let outside: Vec<[f64; 3]> = st
            .liquid
            .pos
            .iter()
            .map(|x| sim.params().to_world(*x))
            .filter(|w| w[0].abs() > 0.005 + 1e-6 || w[1].abs() > 0.005 + 1e-6 || w[2] < -1e-6)
            .collect();
        eprintln!(
            "{backend:?}: {} liquid particles at t = {:.4} s, {} outside the tube",
            st.liquid.len(),
            st.t,
            outside.len()
        );
        assert!(outside.is_empty(), "{backend:?}: liquid outside the vessel at {outside:?}");
        st.liquid.len()
    };
    let n_cpu = run(BackendKind::Cpu);
    assert!(n_cpu < 432, "the suction drew the top layers into the sink");
    gpu_test("a_vessel_of_boxes_holds_its_liquid_on_both_back_ends", |_ctx| {
        assert_eq!(run(BackendKind::Gpu), n_cpu, "both back-ends sank the same particles");
    });
}

/// A pressure outlet and the ambient pressure (`docs/outlet_column.ron`: a sealed column drawn at
/// −5 kPa through an outlet buffer, p_a = 10 kPa) on both back-ends. Passes, on the CPU's state after 100
/// steps (the column expanding into the buffer): the buffer's particles carry the outlet's density and
/// absolute pressure, feel no force, and get the Shepard normal velocity as ṽ; ρ, p equal to 10⁻⁶
/// relative, accelerations to 10⁻⁴ of max |a|, ṽ to 10⁻⁵ of max |v|. Then 300 whole steps of both:
/// positions within 10⁻³ h and the same particles sunk. And the capsule's reaction to blood at p_a:
/// the perfused cube with its capsule and p_a = 10 kPa, 300 steps on both, within 10⁻³ h.
#[test]
fn outlet_and_ambient_pressure_match_cpu() {
    use perfuse::sim::params::OutletRegion;
    let column = perfuse::scenario::Scenario::from_str_with_overrides(
        include_str!("../docs/outlet_column.ron"),
        "docs/outlet_column.ron",
        &[],
    )
    .expect("the probe scenario");
    gpu_test("outlet_and_ambient_pressure_match_cpu", |ctx| {
        let mut cpu = stepped(solver_for(&column), 100);
        let mut gpu = gpu_from(ctx.clone(), &cpu);
        gpu.run_stages(&[Stage::Pass(passes::DENSITY_LIQUID), Stage::Pass(passes::FORCES_LIQUID_XSPH)]).unwrap();
        cpu_evaluate(&mut cpu);
        let (l, p) = (&cpu.st.liquid, &cpu.params);
        let n = l.x.len();
        let ld: Vec<[f32; 4]> = gpu.read_slot(Slot::LiquidDens, n).unwrap();
        let al: Vec<[f32; 4]> = gpu.read_slot(Slot::LiquidAcc, n).unwrap();
        let vl: Vec<[f32; 4]> = gpu.read_slot(Slot::LiquidVelAdv, n).unwrap();
        let v3 = |v: &[[f32; 4]]| v.iter().map(xyz).collect::<Vec<Vec3>>();
        let d_rho = max_abs_diff(&ld.iter().map(|x| x[0]).collect::<Vec<_>>(), &l.rho);
        let d_p = max_abs_diff(&ld.iter().map(|x| x[3]).collect::<Vec<_>>(), &l.p);
        let d_a = max_vec_diff(&v3(&al), &l.a);
        let d_v = max_vec_diff(&v3(&vl), &l.vx);
        let buffer: Vec<usize> = (0..n).filter(|&i| OutletRegion::find(&p.outlets, l.x[i]).is_some()).collect();
        let o = p.outlets[0];
        let moving = buffer.iter().filter(|&&i| l.vx[i].length() > 1e-4).count();
        eprintln!(
            "outlet column after 100 steps: {} of {n} particles in the buffer ({moving} moving); ρ GPU − CPU {d_rho:.3e}, \
             p {d_p:.3e}, a {d_a:.3e} (max {:.3e}), ṽ {d_v:.3e} (max |v| {:.3e})",
            buffer.len(),
            max_len(&l.a),
            max_len(&l.v)
        );
        assert!(!buffer.is_empty() && moving > 0, "the test state must have a moving buffer");
        for &i in &buffer {
            assert_eq!((l.rho[i], l.p[i], l.a[i]), (o.density, o.pressure, Vec3::ZERO), "buffer particle {i}");
            assert!(l.vx[i].cross(o.normal).length() <= 1e-6 * l.vx[i].length().max(1e-12), "ṽ along the normal");
        }
        assert!(d_rho <= 1e-6 * p.rho0_l && d_p <= 1e-6 * max_abs(&l.p));
        assert!(d_a <= 1e-4 * max_len(&l.a));
        assert!(d_v <= 1e-5 * max_len(&l.v) + 1e-9);

        let mut cpu = solver_for(&column);
        let mut gpu = gpu_from(ctx.clone(), &cpu);
        let (gs, cs, d_x) = step_both(&mut cpu, &mut gpu, 300);
        let h = cpu.params.k_liquid.h;
        eprintln!(
            "outlet column, 300 steps (t = {:.3e} s): {} / {} liquid left, max |Δx| {d_x:.3e} m ({:.3e} h)",
            cs.t,
            gs.liquid.len(),
            cs.liquid.len(),
            d_x / h
        );
        assert_eq!(gs.liquid.len(), cs.liquid.len(), "both back-ends sink the same particles");
        assert!(d_x <= 1e-3 * h, "positions diverged");

        // the capsule's reaction to blood at p_a (forces_solid, `outside`), on the perfused cube after 20 steps
        let mut sc = perfused_cube_under_gravity(
            "ambient_capsule",
            "membrane: Some(Membrane(threshold: 0.5, count: 3, radius: 0.5, angle: 0.7853981633974483)),",
        );
        sc.numerics.ambient_pressure = Some(1e3);
        let mut cpu = stepped(solver_for(&sc), 20);
        let mut gpu = gpu_from(ctx, &cpu);
        gpu.run_stages(passes::EVALUATE).unwrap();
        gpu.run_stages(&[Stage::Pass(passes::FORCES_SOLID_XSPH)]).unwrap();
        cpu_evaluate(&mut cpu);
        let s = &cpu.st.solid;
        let as_: Vec<[f32; 4]> = gpu.read_slot(Slot::SolidAcc, s.x.len()).unwrap();
        let d_as = max_vec_diff(&v3(&as_), &s.a);
        // the same forces without the ambient term on the capsule (its particles' and its ghosts'
        // reactions, `ghosts::ghost_on_liquid`'s `outside`): it must matter
        let mut p0 = cpu.params.clone();
        p0.ambient_pressure = 0.0;
        assert!(!cpu.ghosts.is_empty(), "the capsule carries ghost sites by default");
        let a0 = {
            let nb = nbrs(&cpu);
            let st = &cpu.st;
            let g0 = ghosts::ghost_pressure(&p0, &cpu.ghosts, &cpu.ghost_placed, &st.liquid, &st.solid, &nb.liquid);
            let nb = Nbrs { ghosts: nb.ghosts.map(|g| ghosts::GhostNbrs { p: &p0, state: &g0, ..g }), ..nbrs(&cpu) };
            let ctx = force_ctx(&cpu, &p0, &cpu.contacts);
            let st = &cpu.st;
            let seal = forces::forces_liquid(&ctx, &st.liquid, &st.solid, &st.boundary, &nb, false).seal_scale;
            forces::forces_solid(&ctx, &st.solid, &st.liquid, &st.boundary, &nb, false, &seal).a
        };
        let share = max_vec_diff(&a0, &s.a);
        eprintln!(
            "capsule at p_a = 1 kPa after 20 steps: solid a GPU − CPU {d_as:.3e} (max {:.3e}); the ambient term's \
             share {share:.3e}",
            max_len(&s.a)
        );
        assert!(share > 1e-3 * max_len(&s.a), "the ambient term does not act on the capsule");
        assert!(d_as <= 1e-4 * max_len(&s.a));
    });
}

/// Walls that stand in a cavity in the tissue's place (a needle's) show the liquid's nˢ their
/// solid-equivalent mass on both back-ends (the GPU keeps the flag in the high bit of the particle's
/// object word, `BOUNDARY_IN_TISSUE`): a square needle, moving slowly out of a perfused block, between a
/// plate and a post (object 1 of 3: its flagged word is a denormal float's bits, which must reach the
/// shader unflushed for the needle to follow its own motion). (An unmasked index is not caught here:
/// lavapipe's 32-bit offset arithmetic wraps 0x80000001 × the object's size back to object 1.) The
/// liquid's nˢ and pressures after one density pass agree as in `density_passes_match_cpu` — and the
/// walls' share is exercised (nˢ beside the needle moves by more than 0.1 without it); then both
/// back-ends step 40 times with the boundary, liquid and solid within 1e-3 h.
#[test]
fn walls_in_the_tissues_place_match_cpu() {
    gpu_test("walls_in_the_tissues_place_match_cpu", |ctx| {
        let text = "Scenario(name: \"needle\", dimensions: 3, domain: Domain(min: (-0.01, -0.01, -0.004), max: (0.01, 0.01, 0.016)), \
             gravity: (0.0, 0.0, -9.81), \
             liquid: Some(Liquid(density: 1000.0, viscosity: 0.35, stiffness: Some(1e4))), \
             solid: Some(Solid(density: 1000.0, c10: 1e4, c01: 100.0, k_s: 1e4, n_sat: 0.6, k_sat: 1e4, friction: 1e5)), \
             numerics: Numerics(dx_liquid: Some(0.001), dx_solid: Some(0.001), liquid_tension: true), \
             particles: [PerfusedBlock(min: (-0.006, -0.006, 0.0), max: (0.006, 0.006, 0.008), solid_fraction: 0.6, \
             liquid_fraction: 0.4)], \
             boundaries: [Boundary(name: \"plate\", shape: Box(min: (-0.009, -0.009, -0.002), max: (0.009, 0.009, 0.0)), spacing: Some(0.001)), \
             Boundary(name: \"needle\", shape: Box(min: (-0.002, -0.002, 0.003), max: (0.002, 0.002, 0.012)), \
             spacing: Some(0.0005), motion: Translate(velocity: (0.0, 0.0, 0.05))), \
             Boundary(name: \"post\", shape: Box(min: (0.008, 0.008, 0.0), max: (0.009, 0.009, 0.002)), spacing: Some(0.001))], \
             cavities: [Box(min: (-0.002, -0.002, 0.003), max: (0.002, 0.002, 0.012))], duration: 1.0)";
        let sc = perfuse::scenario::Scenario::from_str_named(text, "needle.ron").expect("valid test scene");
        let mut cpu = solver_for(&sc);
        let flagged = cpu.st.boundary.m_sn.iter().filter(|&&m| m > 0.0).count();
        assert!(flagged > 0, "no wall stands in the tissue's place");
        let mut gpu = gpu_from(ctx.clone(), &cpu);
        gpu.run_stages(&[Stage::Pass(passes::DENSITY_LIQUID)]).unwrap();
        let n_s_without = {
            let mut bare = solver_for(&sc);
            bare.st.boundary.m_sn.iter_mut().for_each(|m| *m = 0.0);
            cpu_evaluate(&mut bare);
            bare.st.liquid.n_s.clone()
        };
        cpu_evaluate(&mut cpu);
        let l = &cpu.st.liquid;
        let ld: Vec<[f32; 4]> = gpu.read_slot(Slot::LiquidDens, l.x.len()).unwrap();
        let col = |k: usize| ld.iter().map(|x| x[k]).collect::<Vec<f32>>();
        let (d_ns, d_p) = (max_abs_diff(&col(2), &l.n_s), max_abs_diff(&col(3), &l.p));
        let share = max_abs_diff(&l.n_s, &n_s_without);
        eprintln!(
            "{flagged} wall particles in the tissue's place; liquid nˢ {d_ns:.3e}, p {d_p:.3e} (k_l {:.0}); \
             the walls' share moves nˢ by up to {share:.3}",
            cpu.params.k_l
        );
        assert!(d_ns <= 1e-5 && d_p <= 1e-6 * cpu.params.k_l.max(1.0));
        assert!(share > 0.1, "the walls' solid share is not exercised ({share})");
        let mut cpu = solver_for(&sc);
        let x0 = cpu.st.boundary.x.clone();
        let mut gpu = gpu_from(ctx, &cpu);
        let (g, c, d_x) = step_both(&mut cpu, &mut gpu, 40);
        let h = cpu.params.k_liquid.h;
        let d_b = max_vec_diff(&g.boundary.pos, &c.boundary.pos);
        let moved = max_vec_diff(&x0, &c.boundary.pos);
        eprintln!(
            "40 steps: max |Δx| material {d_x:.3e} m ({:.3e} h), boundary {d_b:.3e} m (the needle moved {moved:.3e} m)",
            d_x / h
        );
        assert!(d_x <= 1e-3 * h, "diverged");
        // the needle's particles follow their own object, not the one a flagged word would name
        assert!(moved > 0.0 && d_b <= 1e-3 * moved, "boundary {d_b:.3e} m off, needle moved {moved:.3e} m");
    });
}
