//! Analysis of simulations: analytic references (`analytic`), the validation cases of SPEC.md §7 with
//! their report and plots (`validate`), PNG charts (`plot`), and the wetting measurements of the
//! surface-tension cases (`wetting`) with their validation case (`wicking`), and the liver cut by the
//! scalpel (`scalpel`).

pub mod analytic;
pub mod dmd;
pub mod frames;
pub mod hemorrhage;
pub mod plot;
pub mod projectile;
pub mod scalpel;
pub mod session;
pub mod validate;
pub mod wetting;
pub mod wicking;
