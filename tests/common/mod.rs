//! Shared test helpers: the GPU harness (`gpu`), small scenes (`scenes`), the shape of a serde value
//! (`shape`) and the validation-report check (`validation`).
#![allow(dead_code, reason = "each test binary uses a different subset")]

pub mod gpu;
pub mod scenes;
pub mod shape;
pub mod validation;
