//! Runs one validation case through `perfuse::analysis::validate` and asserts that every metric passes,
//! printing the table; shared by the CPU (`tests/validation.rs`) and GPU (`tests/gpu_validation.rs`) suites.

use perfuse::analysis::validate::run_validation;
use perfuse::sim::BackendKind;
use std::path::PathBuf;

/// Runs `case` at the `--quick` resolution on `backend`, keeping report and plots under
/// `target/test-artifacts/<artifacts>/<case>/`.
pub fn assert_case_passes(case: &str, backend: BackendKind, artifacts: &str) {
    let out = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/test-artifacts").join(artifacts).join(case);
    let started = std::time::Instant::now();
    let report = run_validation(Some(case), true, &out, backend, false, &[], Default::default())
        .unwrap_or_else(|e| panic!("{case}: {e}"));
    println!("{case} on {backend:?}: {:.1} s", started.elapsed().as_secs_f64());
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
    assert!(failed.is_empty(), "{case} failed on {backend:?}: {failed:?}");
    assert!(out.join("report.json").exists());
}
