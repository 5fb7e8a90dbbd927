//! Analysis of simulations: analytic references (`analytic`), the validation cases of SPEC.md §7 with
//! their report and plots (`validate`), PNG charts (`plot`), and the wetting measurements of the
//! surface-tension cases (`wetting`) with their validation case (`wicking`), the liver cut by the
//! scalpel (`scalpel`), the syringe (`syringe`), and DMD (`dmd`) with its validation cases on the oscillating wall and the broken
//! dam (`dmd_cases`).

pub mod analytic;
pub mod capsule;
pub mod dmd;
pub mod dmd_cases;
pub mod frames;
pub mod hemorrhage;
pub mod liver_rest;
pub mod plot;
pub mod projectile;
pub mod relaxation;
pub mod scalpel;
pub mod session;
pub mod syringe;
pub mod validate;
pub mod wetting;
pub mod wicking;
