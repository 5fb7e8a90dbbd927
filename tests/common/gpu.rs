//! GPU test harness (STYLE §5.5, after rerun's `context_test.rs` and wgpu's `tests/src/run.rs`).
//!
//! * One shared adapter (`LazyLock`): Vulkan only (the GL llvmpipe also shows up and is never used),
//!   `PERFUSE_ADAPTER` picks by name substring, otherwise the Vulkan software adapter (lavapipe,
//!   `DeviceType::Cpu`) is preferred so results are the same on every machine; its `AdapterInfo` is
//!   printed once. `InstanceFlags::VALIDATION` is on.
//! * A fresh device per test, and a process-wide mutex serialising GPU tests (`cargo test` runs tests
//!   on threads; wgpu's own suite relies on nextest's process per test).
//! * The body runs inside validation and out-of-memory error scopes; any error fails the test.
//! * No adapter is a failure telling you to run `.ci/run`; tests are skipped only under an explicit,
//!   loudly printed `PERFUSE_SKIP_GPU_TESTS=1`.
//! * Expectations are data: [`EXPECTATIONS`] lists adapter-name substrings with `Skip`/`ExpectFail`,
//!   each with its reason; an unexpected pass of an `ExpectFail` fails.

use perfuse::sim::gpu::GpuContext;
use perfuse::sim::gpu::device::{create_instance, select_adapter};
use std::sync::{LazyLock, Mutex};

/// What a known issue does on a matching adapter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Behaviour {
    Skip,
    ExpectFail,
}

/// A known adapter-specific issue: (test name, adapter-name substring, behaviour, reason).
pub type Expectation = (&'static str, &'static str, Behaviour, &'static str);

/// Known issues. Empty: every test passes on lavapipe (Mesa 22.3) at the time of writing.
pub const EXPECTATIONS: &[Expectation] = &[];

static GPU_LOCK: Mutex<()> = Mutex::new(());

static ADAPTER: LazyLock<Result<wgpu::Adapter, String>> = LazyLock::new(|| {
    let instance = {
        let _ = create_instance(); // sets XDG_RUNTIME_DIR if needed
        wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: wgpu::Backends::VULKAN,
            flags: wgpu::InstanceFlags::VALIDATION,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        })
    };
    let wanted = std::env::var("PERFUSE_ADAPTER").ok().filter(|s| !s.is_empty());
    match select_adapter(&instance, wanted.as_deref(), true) {
        Ok(a) => {
            let i = a.get_info();
            eprintln!(
                "[gpu tests] adapter: {} ({:?}, {:?}, driver {} {})",
                i.name, i.backend, i.device_type, i.driver, i.driver_info
            );
            Ok(a)
        }
        Err(e) => Err(e.to_string()),
    }
});

fn skip_requested() -> bool {
    std::env::var("PERFUSE_SKIP_GPU_TESTS").is_ok_and(|v| v == "1")
}

/// Runs `body` with a fresh device on the shared test adapter, serialised with every other GPU test.
/// Returns `false` if the test was skipped.
pub fn gpu_test(name: &str, body: impl FnOnce(GpuContext)) -> bool {
    if skip_requested() {
        eprintln!("\n!!!!!!!! PERFUSE_SKIP_GPU_TESTS=1: SKIPPING GPU TEST `{name}` — NOTHING WAS CHECKED !!!!!!!!\n");
        return false;
    }
    let _guard = GPU_LOCK.lock().unwrap_or_else(|p| p.into_inner());
    let adapter = match &*ADAPTER {
        Ok(a) => a,
        Err(e) => panic!(
            "no GPU adapter for `{name}`: {e}\nrun `.ci/run` (it installs Mesa's lavapipe: mesa-vulkan-drivers libvulkan1), \
             or set PERFUSE_SKIP_GPU_TESTS=1 to skip GPU tests explicitly"
        ),
    };
    let info = adapter.get_info();
    let expectation =
        EXPECTATIONS.iter().find(|(t, sub, _, _)| *t == name && info.name.to_lowercase().contains(&sub.to_lowercase()));
    if let Some((_, _, Behaviour::Skip, reason)) = expectation {
        eprintln!("[gpu tests] SKIP `{name}` on `{}`: {reason}", info.name);
        return false;
    }
    let ctx = GpuContext::from_adapter(adapter).expect("device");
    let device = ctx.device.clone();
    let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| body(ctx)));
    let _ =
        device.poll(wgpu::PollType::Wait { submission_index: None, timeout: Some(std::time::Duration::from_secs(60)) });
    let oom_err = pollster::block_on(oom.pop());
    let val_err = pollster::block_on(validation.pop());
    let failed = result.is_err() || oom_err.is_some() || val_err.is_some();
    match expectation {
        Some((_, _, Behaviour::ExpectFail, reason)) => {
            assert!(
                failed,
                "`{name}` was expected to fail on `{}` ({reason}) but passed: remove the expectation",
                info.name
            );
            eprintln!("[gpu tests] `{name}` failed as expected on `{}`: {reason}", info.name);
        }
        _ => {
            if let Err(p) = result {
                std::panic::resume_unwind(p);
            }
            assert!(oom_err.is_none(), "out-of-memory error: {oom_err:?}");
            assert!(val_err.is_none(), "validation error: {val_err:?}");
        }
    }
    true
}
