//! Perfuse — a biphasic SPH surgical simulator: hyperelastic tissue and Newtonian blood as two
//! interpenetrating particle sets (Chang, UCLA 2020, chapters 2–5; restated in `SPEC.md`).
//!
//! * [`scenario`] — what is simulated (RON files, validation, generators).
//! * [`sim`] — how: one [`sim::Simulation`] API; `sim::cpu` is the rayon reference solver.
//! * [`analysis`] — analytic references, validation cases, reports and plots.
//! * [`output`] — CSV frames and `summary.json` of headless runs.
//! * [`bench`](mod@bench) — particle-steps per second of the back-ends (`perfuse bench`).
//!
//! **Determinism.** Neighbour sums run in a canonical order (grid cell offsets, then ascending particle
//! index), each particle's sum is sequential, and reductions are min/max: two runs of a scenario on one
//! back-end produce bit-identical states (`State::hash`).

pub mod analysis;
pub mod app;
pub mod bench;
pub mod output;
pub mod render;
pub mod replay;
pub mod scenario;
pub mod sim;
#[cfg(test)]
mod test_dir;
