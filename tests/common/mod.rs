//! Shared test helpers: the GPU harness (`gpu`), small scenes (`scenes`) and the validation-report check
//! (`validation`).
#![allow(dead_code, reason = "each test binary uses a different subset")]

pub mod gpu;
pub mod scenes;
pub mod validation;
