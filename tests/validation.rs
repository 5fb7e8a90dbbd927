//! The validation cases of SPEC.md §7 at the reduced (`--quick`) resolutions, each against its analytic
//! reference with the tolerances (issue: core). Reports and PNG plots are kept under
//! `target/test-artifacts/validation/<case>/` for a person to look at.

use perfuse::analysis::validate::run_validation;
use perfuse::sim::BackendKind;
use std::path::PathBuf;

fn run_case(case: &str) {
    let out = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/test-artifacts/validation").join(case);
    let report =
        run_validation(Some(case), true, &out, BackendKind::Cpu, false).unwrap_or_else(|e| panic!("{case}: {e}"));
    assert!(!report.cases.is_empty(), "{case}: no metric reported");
    let mut failed = Vec::new();
    for c in &report.cases {
        println!(
            "{:<14} {:<40} {:>10.5} (tol {:>8.5}) {}",
            c.name,
            c.metric,
            c.value,
            c.tolerance,
            if c.pass { "pass" } else { "FAIL" }
        );
        if !c.pass {
            failed.push(format!("{} = {} > {}", c.metric, c.value, c.tolerance));
        }
    }
    assert!(failed.is_empty(), "{case} failed: {failed:?}");
    assert!(out.join("report.json").exists());
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
