//! Analysis of simulations: analytic references (`analytic`), the validation cases of SPEC.md §7 with
//! their report and plots (`validate`), and PNG charts (`plot`).

pub mod analytic;
pub mod dmd;
pub mod hemorrhage;
pub mod plot;
pub mod session;
pub mod validate;
