//! The validation cases of SPEC.md §7 at the reduced (`--quick`) resolutions on the GPU back-end
//! (issue: GPU back-end — "at least Poiseuille, Brinkman and hydrostatic in the test suite"), with the
//! same tolerances as the CPU suite (tests/validation.rs). They run on the device of
//! `GpuContext::new` (lavapipe here) with batched stepping (`Simulation::advance`); reports and plots go
//! to `target/test-artifacts/gpu-validation/<case>/`. Serialised with each other (one device at a
//! time). `PERFUSE_SKIP_GPU_TESTS=1` skips them loudly, as the other GPU tests. On lavapipe with 2
//! cores they took 33 s (Poiseuille), 81 s (Brinkman) and 87 s (hydrostatic) on 2026-12-02, each with a
//! CPU validation run beside it.

mod common;

use perfuse::sim::BackendKind;
use std::sync::Mutex;

static LOCK: Mutex<()> = Mutex::new(());

fn run_case(case: &str) {
    if std::env::var("PERFUSE_SKIP_GPU_TESTS").is_ok_and(|v| v == "1") {
        eprintln!(
            "\n!!!!!!!! PERFUSE_SKIP_GPU_TESTS=1: SKIPPING GPU VALIDATION `{case}` — NOTHING WAS CHECKED !!!!!!!!\n"
        );
        return;
    }
    let _guard = LOCK.lock().unwrap_or_else(|p| p.into_inner());
    common::validation::assert_case_passes(case, BackendKind::Gpu, "gpu-validation");
}

#[test]
fn gpu_poiseuille_startup_within_5_percent() {
    run_case("poiseuille");
}

#[test]
fn gpu_brinkman_steady_within_4_percent() {
    run_case("brinkman");
}

#[test]
fn gpu_hydrostatic_column_bottom_pressure_within_2_percent() {
    run_case("hydrostatic");
}
