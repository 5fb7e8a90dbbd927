//! Shared test helpers: the GPU harness (`gpu`) and small scenes (`scenes`).
#![allow(dead_code, reason = "each test binary uses a different subset")]

pub mod gpu;
pub mod scenes;
