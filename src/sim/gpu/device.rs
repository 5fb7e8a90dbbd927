//! Adapter and device acquisition for the GPU back-end (STYLE §5.5, STACK "The software adapter").
//!
//! Preference order: the adapter named by `PERFUSE_ADAPTER` (case-insensitive substring of
//! `AdapterInfo::name`), else a hardware adapter (discrete, then integrated), else the Vulkan software
//! adapter (Mesa lavapipe, reported as "llvmpipe (LLVM …)", `DeviceType::Cpu`). GL adapters are never
//! chosen: the GL llvmpipe is slower and lacks the storage-buffer limits the passes need. The device
//! requests the adapter's own limits (lavapipe: 32 storage buffers per stage; the default is 8), so the
//! per-pass binding tables of `bindings.rs` may use up to `MIN_STORAGE_BUFFERS_PER_STAGE`.

use std::sync::Arc;

/// Storage buffers per shader stage the passes need at most (`forces_solid` binds the most).
pub const MIN_STORAGE_BUFFERS_PER_STAGE: u32 = 24;

/// Why the GPU back-end could not start.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GpuError {
    #[error(
        "no usable GPU adapter (Vulkan, Metal or DX12) was found{detail}; install a Vulkan driver \
         (on Debian/Ubuntu: `apt-get install mesa-vulkan-drivers libvulkan1` for the lavapipe software \
         adapter) or run with `--backend cpu`"
    )]
    NoAdapter { detail: String },
    #[error("PERFUSE_ADAPTER=`{wanted}` matches no adapter; available: {available}")]
    AdapterNotFound { wanted: String, available: String },
    #[error(
        "adapter `{adapter}` offers {have} storage buffers per shader stage, the simulation needs {need}; \
         pick another adapter with PERFUSE_ADAPTER or run with `--backend cpu`"
    )]
    InsufficientLimits { adapter: String, have: u32, need: u32 },
    #[error("could not create a device on `{adapter}`: {source}")]
    RequestDevice { adapter: String, source: wgpu::RequestDeviceError },
    #[error("GPU validation or out-of-memory error in {context}: {message}")]
    Validation { context: String, message: String },
    #[error("GPU readback of `{buffer}` failed: {message}")]
    Readback { buffer: String, message: String },
    #[error("GPU wait failed: {0}")]
    Poll(#[from] wgpu::PollError),
}

/// A device and its queue, plus what was chosen (for logs and test expectations).
#[derive(Clone, Debug)]
pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub limits: wgpu::Limits,
    /// Whether the device has `TIMESTAMP_QUERY` (per-pass GPU timers).
    pub timestamps: bool,
}

/// Sets `XDG_RUNTIME_DIR` to a private 0700 directory if it is unset, which silences the
/// "XDG_RUNTIME_DIR is invalid" errors Mesa prints for every instance on headless machines. The
/// directory is the user's own (`perfuse-xdg-<uid>` in the temp directory, as `.ci/run` names it), so
/// runs do not leave one behind each; where that name is taken by another user, one per process.
fn ensure_runtime_dir() {
    if std::env::var_os("XDG_RUNTIME_DIR").is_some() {
        return;
    }
    let tmp = std::env::temp_dir();
    let dir = match private_dir(&tmp.join(format!("perfuse-xdg-{}", user_tag()))) {
        Some(d) => Some(d),
        None => private_dir(&tmp.join(format!("perfuse-xdg-{}-{}", user_tag(), std::process::id()))),
    };
    if let Some(dir) = dir {
        // SAFETY: called before any wgpu instance exists; the variable is only read by drivers.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", &dir) };
    }
}

/// The current user's id where the platform shows it (Linux: the owner of `/proc/self`, the process's
/// effective user), else "user".
fn user_tag() -> String {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let Ok(m) = std::fs::metadata("/proc/self") {
            return m.uid().to_string();
        }
    }
    String::from("user")
}

/// `dir`, created if missing, when it is a directory this process owns and can make 0700.
fn private_dir(dir: &std::path::Path) -> Option<std::path::PathBuf> {
    std::fs::create_dir_all(dir).ok()?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::{MetadataExt, PermissionsExt};
        let mine = std::fs::metadata("/proc/self").map(|m| m.uid()).ok()?;
        let m = std::fs::symlink_metadata(dir).ok()?;
        if !m.is_dir() || m.uid() != mine {
            return None;
        }
        std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o700)).ok()?;
    }
    Some(dir.to_path_buf())
}

/// The instance: native back-ends without GL (STACK: the GL llvmpipe must not be picked).
pub fn create_instance() -> wgpu::Instance {
    ensure_runtime_dir();
    wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::VULKAN | wgpu::Backends::METAL | wgpu::Backends::DX12,
        // Indirect-dispatch validation would add one extra dispatch per indirect dispatch of a batch;
        // our arguments are the host's own workgroup counts or zero (batch.wgsl), never out of range.
        flags: wgpu::InstanceFlags::from_build_config()
            .with_env()
            .difference(wgpu::InstanceFlags::VALIDATION_INDIRECT_CALL),
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    })
}

/// Whether `--backend auto` should pick the GPU: a hardware adapter (not the software rasteriser) is
/// present, or `PERFUSE_ADAPTER` names one explicitly. On a machine with only lavapipe the rayon solver
/// is faster (README: Performance), so auto picks the CPU there.
pub fn hardware_adapter_available() -> bool {
    if std::env::var("PERFUSE_ADAPTER").is_ok_and(|v| !v.is_empty()) {
        return true;
    }
    let instance = create_instance();
    pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()))
        .iter()
        .map(|a| a.get_info())
        .any(|i| i.backend != wgpu::Backend::Gl && i.device_type != wgpu::DeviceType::Cpu)
}

/// Rank of an adapter: lower is preferred (hardware first, then the Vulkan software adapter).
fn preference(info: &wgpu::AdapterInfo) -> u32 {
    match info.device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

/// Picks the adapter: `wanted` (substring of the name) if given, else the best by `preference`.
/// With `prefer_software` the Vulkan CPU adapter wins (tests: reproducible on every machine).
pub fn select_adapter(
    instance: &wgpu::Instance,
    wanted: Option<&str>,
    prefer_software: bool,
) -> Result<wgpu::Adapter, GpuError> {
    select_adapter_where(instance, wanted, prefer_software, |_| true)
}

/// [`select_adapter`] among the adapters `accept` lets through (the viewer: those that can present to
/// its window).
pub fn select_adapter_where(
    instance: &wgpu::Instance,
    wanted: Option<&str>,
    prefer_software: bool,
    accept: impl Fn(&wgpu::Adapter) -> bool,
) -> Result<wgpu::Adapter, GpuError> {
    let adapters: Vec<wgpu::Adapter> = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()))
        .into_iter()
        .filter(|a| a.get_info().backend != wgpu::Backend::Gl && accept(a))
        .collect();
    let available = adapters
        .iter()
        .map(|a| format!("`{}` ({:?}, {:?})", a.get_info().name, a.get_info().backend, a.get_info().device_type))
        .collect::<Vec<_>>()
        .join(", ");
    if let Some(w) = wanted {
        let wl = w.to_lowercase();
        return adapters
            .into_iter()
            .find(|a| a.get_info().name.to_lowercase().contains(&wl))
            .ok_or(GpuError::AdapterNotFound { wanted: w.to_string(), available });
    }
    if adapters.is_empty() {
        return Err(GpuError::NoAdapter { detail: " (only GL or no adapters)".into() });
    }
    let best = adapters.into_iter().min_by_key(|a| {
        let info = a.get_info();
        let rank = preference(&info);
        if prefer_software {
            if info.device_type == wgpu::DeviceType::Cpu && info.backend == wgpu::Backend::Vulkan {
                0
            } else {
                1 + rank
            }
        } else {
            rank
        }
    });
    best.ok_or(GpuError::NoAdapter { detail: format!(" (candidates: {available})") })
}

impl GpuContext {
    /// Acquires an adapter (honouring `PERFUSE_ADAPTER`) and a device with the adapter's limits.
    pub fn new() -> Result<GpuContext, GpuError> {
        let instance = create_instance();
        let wanted = std::env::var("PERFUSE_ADAPTER").ok().filter(|s| !s.is_empty());
        let adapter = select_adapter(&instance, wanted.as_deref(), false)?;
        Self::from_adapter(&adapter)
    }

    /// Creates a device on `adapter` with the adapter's limits (checked against what the passes need).
    pub fn from_adapter(adapter: &wgpu::Adapter) -> Result<GpuContext, GpuError> {
        let info = adapter.get_info();
        log::info!(
            "GPU adapter: {} ({:?}, {:?}, driver {} {})",
            info.name,
            info.backend,
            info.device_type,
            info.driver,
            info.driver_info
        );
        let limits = adapter.limits();
        if limits.max_storage_buffers_per_shader_stage < MIN_STORAGE_BUFFERS_PER_STAGE {
            return Err(GpuError::InsufficientLimits {
                adapter: info.name.clone(),
                have: limits.max_storage_buffers_per_shader_stage,
                need: MIN_STORAGE_BUFFERS_PER_STAGE,
            });
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("perfuse.device"),
            // Timestamp queries (per-pass timers, `GpuSolver::pass_times`) where the adapter has them.
            required_features: adapter.features() & wgpu::Features::TIMESTAMP_QUERY,
            required_limits: limits.clone(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|source| GpuError::RequestDevice { adapter: info.name.clone(), source })?;
        let timestamps = device.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        Ok(GpuContext { device, queue, info, limits, timestamps })
    }
}

/// Captures the validation and out-of-memory errors raised on this thread between [`ErrorScope::push`]
/// and [`ErrorScope::pop`]. wgpu's error scopes are per thread and nest, so the innermost scope gets
/// exactly the errors of the work it brackets — also when a caller has pushed scopes of its own (the
/// test harness does: without this, a shader that failed to parse reached the harness's scope, never
/// the solver, and the solver only noticed when a batch ran no step).
pub struct ErrorScope {
    validation: wgpu::ErrorScopeGuard,
    oom: wgpu::ErrorScopeGuard,
}

impl ErrorScope {
    pub fn push(device: &wgpu::Device) -> ErrorScope {
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        ErrorScope { validation, oom }
    }

    /// Pops both scopes (innermost first) and returns the first captured error as a
    /// [`GpuError::Validation`] naming `context`.
    pub fn pop(self, context: &str) -> Result<(), GpuError> {
        let oom = pollster::block_on(self.oom.pop());
        let validation = pollster::block_on(self.validation.pop());
        match validation.or(oom) {
            None => Ok(()),
            Some(e) => Err(GpuError::Validation { context: context.to_string(), message: e.to_string() }),
        }
    }

    /// Runs `f` inside a scope; an error the scope captured is reported before `f`'s own result
    /// (it is the cause: e.g. a batch that ran no step because its pipelines are invalid).
    pub fn around<T>(
        device: &wgpu::Device,
        context: &str,
        f: impl FnOnce() -> Result<T, GpuError>,
    ) -> Result<T, GpuError> {
        let scope = ErrorScope::push(device);
        let result = f();
        scope.pop(context)?;
        result
    }
}

/// Keeps the device's uncaptured errors (validation, OOM raised outside any [`ErrorScope`]) for the
/// solver to report as [`GpuError`] instead of wgpu's default panic.
#[derive(Clone, Default)]
pub struct ErrorSink(Arc<std::sync::Mutex<Vec<String>>>);

impl ErrorSink {
    pub fn install(device: &wgpu::Device) -> ErrorSink {
        let sink = ErrorSink::default();
        let inner = sink.0.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            if let Ok(mut v) = inner.lock() {
                v.push(e.to_string());
            }
        }));
        sink
    }

    /// Returns the first recorded error, if any, as a [`GpuError::Validation`].
    pub fn take(&self, context: &str) -> Result<(), GpuError> {
        let mut v = match self.0.lock() {
            Ok(v) => v,
            Err(p) => p.into_inner(),
        };
        if v.is_empty() {
            return Ok(());
        }
        let message = v.join("; ");
        v.clear();
        Err(GpuError::Validation { context: context.to_string(), message })
    }
}
