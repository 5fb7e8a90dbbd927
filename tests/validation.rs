//! The validation cases of SPEC.md §7 at the reduced (`--quick`) resolutions, each against its analytic
//! reference with the tolerances (issue: core). Reports and PNG plots are kept under
//! `target/test-artifacts/validation/<case>/` for a person to look at.

mod common;

use perfuse::sim::BackendKind;

fn run_case(case: &str) {
    common::validation::assert_case_passes(case, BackendKind::Cpu, "validation");
}

#[test]
fn poiseuille_startup_within_5_percent() {
    run_case("poiseuille");
}

#[test]
fn brinkman_steady_within_4_percent() {
    run_case("brinkman");
}

#[test]
fn brinkman_convergence_monotone_and_finest_within_2_percent() {
    run_case("convergence");
}

#[test]
fn hydrostatic_column_bottom_pressure_within_2_percent() {
    run_case("hydrostatic");
}

#[test]
fn cantilever_first_mode_within_5_percent() {
    run_case("cantilever");
}
