//! The wgpu device texsyn runs on: adapter selection, device creation and turning wgpu's
//! asynchronous validation errors into [`Error::Gpu`].
//!
//! * [`GpuContext::headless`] picks an adapter from the environment (`TEXSYN_BACKEND`,
//!   `TEXSYN_ADAPTER`); this is what the CLI uses.
//! * [`GpuContext::with_options`] does the same from explicit [`GpuOptions`] and reads no
//!   `TEXSYN_*` variable, for library users and tests.
//! * [`GpuContext::from_device`] wraps a device the caller created itself.
//!
//! No window or surface is involved: synthesis is compute only.

use std::fmt::Write as _;
use std::sync::{Arc, Mutex};

use crate::error::{Error, Result};

/// Environment variable read by [`GpuContext::headless`] for [`GpuOptions::backend`].
pub const BACKEND_ENV: &str = "TEXSYN_BACKEND";
/// Environment variable read by [`GpuContext::headless`] for [`GpuOptions::adapter`].
pub const ADAPTER_ENV: &str = "TEXSYN_ADAPTER";
/// Environment variable read by [`GpuContext::headless`] for
/// [`GpuOptions::pin_cpu_threads`] (`0` or `1`).
pub const PIN_CPU_THREADS_ENV: &str = "TEXSYN_PIN_CPU_THREADS";

/// How [`GpuContext::with_options`] chooses its adapter.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct GpuOptions {
    /// Graphics API: `vulkan`, `gl`, `metal`, `dx12` or `all` (case-insensitive; a
    /// comma-separated list such as `vulkan,gl` also works). `None` (or empty): wgpu's
    /// primary backends (Vulkan, Metal, DX12), falling back to GL only if none of them
    /// offers a usable adapter.
    pub backend: Option<String>,
    /// Which adapter: a case-insensitive substring of its name (`llvmpipe`, `nvidia`), or a
    /// decimal index into the list of adapters found (the list is printed in the
    /// [`Error::NoAdapter`] message). `None` (or empty): prefer a discrete GPU, then an
    /// integrated one, then a virtual one, then a CPU implementation such as lavapipe;
    /// adapters without compute shaders are skipped.
    pub adapter: Option<String>,
    /// On a CPU adapter (lavapipe) on Linux, bind the driver's worker threads to
    /// separate cores (see `super::cpu_threads`: without it the scheduler can run them
    /// all on one core, nearly doubling the synthesis time on 2 cores). `None`: yes.
    /// GPUs and other systems are never affected.
    pub pin_cpu_threads: Option<bool>,
}

impl GpuOptions {
    /// Options from `TEXSYN_BACKEND`, `TEXSYN_ADAPTER` and `TEXSYN_PIN_CPU_THREADS` (unset
    /// or empty: automatic; the last is `0` to leave the threads alone).
    pub fn from_env() -> Self {
        let var = |name| std::env::var(name).ok().filter(|v| !v.trim().is_empty());
        GpuOptions {
            backend: var(BACKEND_ENV),
            adapter: var(ADAPTER_ENV),
            pin_cpu_threads: var(PIN_CPU_THREADS_ENV).map(|v| v.trim() != "0"),
        }
    }
}

/// wgpu's default instance flags without `VALIDATION_INDIRECT_CALL`, then wgpu's
/// environment variables (`WGPU_VALIDATION_INDIRECT_CALL=1` turns it back on). texsyn
/// records no indirect dispatch or draw, and the validation's pipelines, built with every
/// device, are a large part of device creation on a CPU driver.
fn instance_flags() -> wgpu::InstanceFlags {
    wgpu::InstanceFlags::default()
        .difference(wgpu::InstanceFlags::VALIDATION_INDIRECT_CALL)
        .with_env()
}

/// A wgpu device and queue, plus what texsyn needs to know about them.
///
/// Cloning is cheap (wgpu handles are reference counted) and shares the device.
#[derive(Clone, Debug)]
pub struct GpuContext {
    /// The logical device. [`headless`](Self::headless) / [`with_options`](Self::with_options)
    /// create it with the adapter's own limits (see [`limits`](Self::limits)) and no
    /// optional features, except `MAPPABLE_PRIMARY_BUFFERS` on a CPU device (lavapipe),
    /// where it saves a copy of the analysis tables on upload. Nothing requires it.
    pub device: wgpu::Device,
    /// The device's queue.
    pub queue: wgpu::Queue,
    /// The adapter the device runs on. Always known: wgpu reports it for any device,
    /// including one passed to [`from_device`](Self::from_device).
    pub adapter_info: wgpu::AdapterInfo,
    /// Errors that escaped every error scope (see [`take_uncaptured_errors`](Self::take_uncaptured_errors)).
    uncaptured: Arc<Mutex<Vec<String>>>,
    /// The synthesis passes' pipelines, shared by every synthesizer on this device.
    pipelines: Arc<std::sync::OnceLock<Arc<crate::gpu::synth::PassPipelines>>>,
}

impl GpuContext {
    /// A device without any window or surface, chosen from the environment:
    /// `TEXSYN_BACKEND` and `TEXSYN_ADAPTER`, as described on [`GpuOptions`].
    ///
    /// This is the only constructor that reads those variables (wgpu itself still honours
    /// its debugging variables such as `WGPU_DEBUG` / `WGPU_VALIDATION`).
    pub fn headless() -> Result<Self> {
        Self::with_options(GpuOptions::from_env())
    }

    /// A device without any window or surface, chosen by `options`; reads no `TEXSYN_*`
    /// environment variable.
    ///
    /// Errors: [`Error::InvalidParameter`] for an unknown backend name,
    /// [`Error::NoAdapter`] when no adapter matches (the message lists those found), and
    /// [`Error::Gpu`] when the chosen adapter refuses to create a device.
    pub fn with_options(options: GpuOptions) -> Result<Self> {
        use super::cpu_threads::{pin_threads_named, INIT_THREAD_NAME};
        if options.pin_cpu_threads == Some(false) {
            return Self::create(&options);
        }
        // On a thread of its own, so that the threads the driver starts meanwhile carry
        // its name (see `cpu_threads`). Where no thread can be started, here, unbound.
        let spawned = std::thread::Builder::new()
            .name(INIT_THREAD_NAME.into())
            .spawn({
                let options = options.clone();
                move || Self::create(&options)
            });
        let ctx = match spawned {
            Ok(thread) => thread
                .join()
                .map_err(|_| Error::Gpu("creating the device panicked".into()))??,
            Err(_) => return Self::create(&options),
        };
        if ctx.adapter_info.device_type == wgpu::DeviceType::Cpu {
            pin_threads_named(INIT_THREAD_NAME);
        }
        Ok(ctx)
    }

    fn create(options: &GpuOptions) -> Result<Self> {
        let backend = options
            .backend
            .as_deref()
            .map(str::trim)
            .filter(|s| !s.is_empty());
        let selector = options
            .adapter
            .as_deref()
            .map(str::trim)
            .filter(|s| !s.is_empty());
        let stages = backend_stages(backend)?;

        // Adapters seen so far, for the error message.
        let mut seen: Vec<wgpu::AdapterInfo> = Vec::new();
        let mut chosen = None;
        for backends in stages {
            let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
                backends,
                flags: instance_flags(),
                ..wgpu::InstanceDescriptor::new_without_display_handle()
            });
            let adapters = pollster::block_on(instance.enumerate_adapters(backends));
            let first_index = seen.len();
            seen.extend(adapters.iter().map(wgpu::Adapter::get_info));
            match select(&adapters, first_index, selector)? {
                Some(i) => {
                    chosen = Some(adapters[i].clone());
                    break;
                }
                None => continue,
            }
        }

        let Some(adapter) = chosen else {
            return Err(Error::NoAdapter(no_adapter_message(
                backend, selector, &seen,
            )));
        };
        Self::from_adapter(&adapter)
    }

    /// Create the device on `adapter` with the adapter's own limits and no optional
    /// features but mappable storage buffers on a CPU device.
    fn from_adapter(adapter: &wgpu::Adapter) -> Result<Self> {
        let info = adapter.get_info();
        // On a CPU device (lavapipe) every buffer lives in host memory anyway: storage
        // buffers that can be mapped take the analysis tables without wgpu's staging copy
        // (see `GpuSynthesizer::new`). Not asked of GPUs, where mappable storage is slow.
        let mappable = wgpu::Features::MAPPABLE_PRIMARY_BUFFERS;
        let required_features =
            if info.device_type == wgpu::DeviceType::Cpu && adapter.features().contains(mappable) {
                mappable
            } else {
                wgpu::Features::empty()
            };
        let descriptor = wgpu::DeviceDescriptor {
            label: Some("texsyn"),
            required_features,
            // The adapter's real limits rather than the WebGPU defaults, so large
            // storage buffers and textures are allowed where the hardware allows them.
            required_limits: adapter.limits(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        };
        let (device, queue) =
            pollster::block_on(adapter.request_device(&descriptor)).map_err(|e| {
                Error::Gpu(format!(
                    "cannot create a device on {}: {}",
                    describe_info(&info),
                    error_chain(&e)
                ))
            })?;
        Ok(Self::wrap(device, queue, info))
    }

    /// Wrap a device the caller created (any features and limits).
    ///
    /// `adapter_info` is taken from [`wgpu::Device::adapter_info`]. Like the other
    /// constructors this installs texsyn's uncaptured-error handler on the device (see
    /// [`take_uncaptured_errors`](Self::take_uncaptured_errors)), replacing any handler the
    /// caller had set; set yours again afterwards if you need it. Wrap a device once and
    /// share clones of the context: a second `from_device` on the same device is another
    /// context (texsyn objects of one are refused by the other), and its handler takes
    /// the device's errors over from the first.
    pub fn from_device(device: wgpu::Device, queue: wgpu::Queue) -> Self {
        let info = device.adapter_info();
        Self::wrap(device, queue, info)
    }

    /// Whether textures can be viewed in another format (sRGB views of the output):
    /// every backend but GL (wgpu's `DownlevelFlags::VIEW_FORMATS`).
    pub fn supports_view_formats(&self) -> bool {
        self.adapter_info.backend != wgpu::Backend::Gl
    }

    fn wrap(device: wgpu::Device, queue: wgpu::Queue, adapter_info: wgpu::AdapterInfo) -> Self {
        let uncaptured = Arc::new(Mutex::new(Vec::new()));
        let sink = Arc::clone(&uncaptured);
        // wgpu's default handler panics; log instead, and keep the message so that
        // `take_uncaptured_errors` can turn it into an `Error::Gpu`.
        device.on_uncaptured_error(Arc::new(move |error: wgpu::Error| {
            let message = describe_wgpu_error(&error);
            eprintln!("texsyn: uncaptured wgpu error: {message}");
            if let Ok(mut errors) = sink.lock() {
                // Bounded: a broken loop must not grow this forever.
                if errors.len() < 64 {
                    errors.push(message);
                }
            }
        }));
        GpuContext {
            device,
            queue,
            adapter_info,
            uncaptured,
            pipelines: Default::default(),
        }
    }

    /// The synthesis passes' bind group layout and pipelines on this device.
    /// Whether `self` and `other` are the same context (or clones of one): objects made
    /// on one belong to its device. Compared by the shared pipeline cache, since wgpu's
    /// device equality compares ids, which coincide across instances.
    pub(crate) fn same_as(&self, other: &GpuContext) -> bool {
        Arc::ptr_eq(&self.pipelines, &other.pipelines)
    }

    pub(crate) fn pass_pipelines(&self) -> Arc<crate::gpu::synth::PassPipelines> {
        self.pipelines
            .get_or_init(|| Arc::new(crate::gpu::synth::PassPipelines::new(&self.device)))
            .clone()
    }

    /// Builds the compute pipelines of a 2D synthesis (`anisometric`: along a field) now
    /// instead of on first use, e.g. while an application loads, so that its first
    /// synthesis does not stall (tens of milliseconds on lavapipe, more with some
    /// drivers). Optional: pipelines are otherwise built when first needed. Every
    /// synthesizer on this context shares them.
    pub fn prepare_pipelines(&self, anisometric: bool) -> Result<()> {
        crate::gpu::synth::check_device_limits(&self.limits())?;
        self.pass_pipelines().prepare(self, anisometric)
    }

    /// Builds exactly the pipelines a synthesis of `params` from `analysis` will use,
    /// before any [`GpuSynthesizer`](crate::GpuSynthesizer) exists: e.g. on another
    /// thread while [`GpuSynthesizer::new`](crate::GpuSynthesizer::new) uploads the
    /// analysis, which the CLI does (tens of milliseconds each on lavapipe). Invalid
    /// parameters are the errors [`crate::passes::SynthPlan::new`] gives.
    pub fn prepare_synthesis(
        &self,
        analysis: &crate::Analysis,
        params: &crate::SynthParams,
    ) -> Result<()> {
        crate::gpu::synth::check_device_limits(&self.limits())?;
        self.pass_pipelines()
            .prepare_plan(self, analysis, params, |_| Ok(()))
    }

    /// How many pass pipelines (a pass's shader with one set of constants) texsyn has
    /// built on this context so far. Each takes milliseconds to tens of milliseconds to
    /// build, so a host can check that its frame loop builds none (they are built by
    /// [`Self::prepare_pipelines`], [`Self::prepare_synthesis`],
    /// [`GpuSynthesizer::prepare`](crate::GpuSynthesizer::prepare) and
    /// [`Advection::new`](crate::Advection::new), or on first use). Not counted: the
    /// small pipeline that quantizes a caller's velocity texture, built by an
    /// advection's first [`encode_step_texture`](crate::Advection::encode_step_texture).
    pub fn built_pipelines(&self) -> usize {
        self.pipelines.get().map_or(0, |p| p.built())
    }

    /// One line about the adapter, e.g.
    /// `llvmpipe (LLVM 15.0.6, 256 bits) [Vulkan, Cpu, driver: llvmpipe Mesa 22.3.6 (LLVM 15.0.6)]`.
    pub fn describe(&self) -> String {
        describe_info(&self.adapter_info)
    }

    /// The device's limits (for [`headless`](Self::headless) and
    /// [`with_options`](Self::with_options): the adapter's full limits).
    pub fn limits(&self) -> wgpu::Limits {
        self.device.limits()
    }

    /// Run `f` (which records wgpu calls on this device) inside validation,
    /// out-of-memory and internal error scopes, and turn the first error caught into
    /// [`Error::Gpu`]; on error `f`'s value is dropped.
    ///
    /// Error scopes are per thread: `f` runs on the calling thread, and wgpu calls it
    /// makes from other threads are not covered. Errors surfacing later (e.g. at
    /// `queue.submit`) need their own scope or [`take_uncaptured_errors`](Self::take_uncaptured_errors).
    pub fn scoped<T>(&self, f: impl FnOnce() -> T) -> Result<T> {
        let internal = self.device.push_error_scope(wgpu::ErrorFilter::Internal);
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let value = f();
        // Pop in reverse order of pushing (wgpu panics otherwise). Each pop takes effect
        // immediately; awaiting only fetches the result.
        let validation = validation.pop();
        let oom = oom.pop();
        let internal = internal.pop();
        let errors = [
            pollster::block_on(validation),
            pollster::block_on(oom),
            pollster::block_on(internal),
        ];
        match errors.into_iter().flatten().next() {
            Some(error) => Err(Error::Gpu(describe_wgpu_error(&error))),
            None => Ok(value),
        }
    }

    /// Errors that escaped every error scope since the last call (they were also
    /// printed to stderr when they happened), as one [`Error::Gpu`]; `Ok(())` if none.
    pub fn take_uncaptured_errors(&self) -> Result<()> {
        let errors = match self.uncaptured.lock() {
            Ok(mut errors) => std::mem::take(&mut *errors),
            Err(poisoned) => std::mem::take(&mut *poisoned.into_inner()),
        };
        if errors.is_empty() {
            Ok(())
        } else {
            Err(Error::Gpu(errors.join("\n")))
        }
    }

    /// Block until all submitted work has finished.
    pub fn wait_idle(&self) -> Result<()> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| Error::Gpu(format!("waiting for the device: {e}")))
    }
}

/// The backend sets to try in order: the first that yields a matching adapter wins.
fn backend_stages(backend: Option<&str>) -> Result<Vec<wgpu::Backends>> {
    let Some(spec) = backend else {
        return Ok(vec![wgpu::Backends::PRIMARY, wgpu::Backends::GL]);
    };
    let mut backends = wgpu::Backends::empty();
    for name in spec.split(',').map(|s| s.trim().to_ascii_lowercase()) {
        backends |= match name.as_str() {
            "vulkan" | "vk" => wgpu::Backends::VULKAN,
            "gl" | "gles" | "opengl" => wgpu::Backends::GL,
            "metal" | "mtl" => wgpu::Backends::METAL,
            "dx12" | "d3d12" => wgpu::Backends::DX12,
            "all" => wgpu::Backends::PRIMARY | wgpu::Backends::GL,
            _ => {
                return Err(Error::InvalidParameter(format!(
                    "unknown GPU backend \"{name}\" (from {BACKEND_ENV} or the backend \
                     option); expected vulkan, gl, metal, dx12 or all"
                )))
            }
        };
    }
    Ok(vec![backends])
}

/// Index (into `adapters`) of the adapter `selector` asks for, or the preferred one.
/// `first_index` is the index of `adapters[0]` in the overall list shown to users.
fn select(
    adapters: &[wgpu::Adapter],
    first_index: usize,
    selector: Option<&str>,
) -> Result<Option<usize>> {
    let infos: Vec<wgpu::AdapterInfo> = adapters.iter().map(wgpu::Adapter::get_info).collect();
    let has_compute = |i: usize| {
        adapters[i]
            .get_downlevel_capabilities()
            .flags
            .contains(wgpu::DownlevelFlags::COMPUTE_SHADERS)
    };
    let found = match selector {
        Some(sel) => match sel.parse::<usize>() {
            Ok(index) => index
                .checked_sub(first_index)
                .filter(|&i| i < adapters.len()),
            Err(_) => {
                let needle = sel.to_lowercase();
                // Prefer a matching adapter that can run compute shaders.
                let matching: Vec<usize> = (0..infos.len())
                    .filter(|&i| infos[i].name.to_lowercase().contains(&needle))
                    .collect();
                best(&infos, matching.iter().copied().filter(|&i| has_compute(i)))
                    .or_else(|| best(&infos, matching.iter().copied()))
            }
        },
        None => best(&infos, (0..infos.len()).filter(|&i| has_compute(i))),
    };
    if let Some(i) = found {
        if !has_compute(i) {
            return Err(Error::NoAdapter(format!(
                "adapter [{}] {} does not support compute shaders, which texsyn needs; \
                 choose another with {ADAPTER_ENV}",
                first_index + i,
                describe_info(&infos[i])
            )));
        }
    }
    Ok(found)
}

/// The preferred adapter among `candidates`: by device type, then primary backends over
/// GL, then enumeration order.
fn best(infos: &[wgpu::AdapterInfo], candidates: impl Iterator<Item = usize>) -> Option<usize> {
    candidates.min_by_key(|&i| {
        let info = &infos[i];
        let kind = match info.device_type {
            wgpu::DeviceType::DiscreteGpu => 0,
            wgpu::DeviceType::IntegratedGpu => 1,
            wgpu::DeviceType::VirtualGpu => 2,
            wgpu::DeviceType::Cpu => 3,
            wgpu::DeviceType::Other => 4,
        };
        (kind, info.backend == wgpu::Backend::Gl, i)
    })
}

fn no_adapter_message(
    backend: Option<&str>,
    selector: Option<&str>,
    seen: &[wgpu::AdapterInfo],
) -> String {
    let backends = backend.unwrap_or("vulkan/metal/dx12, then gl");
    let mut message = match (selector, seen.is_empty()) {
        (Some(sel), _) => format!(
            "no adapter matches \"{sel}\" ({ADAPTER_ENV} or the adapter option takes a \
             case-insensitive part of an adapter name, or its index in the list below)"
        ),
        (None, true) => "no adapters found".to_string(),
        (None, false) => "no adapter supports compute shaders".to_string(),
    };
    let _ = write!(message, "; backends tried: {backends}");
    if seen.is_empty() {
        let _ = write!(
            message,
            "; {ADAPTER_ENV} has nothing to choose from; \
             try another backend with {BACKEND_ENV}=vulkan|gl|metal|dx12|all"
        );
    } else {
        message.push_str("; adapters found:");
        for (i, info) in seen.iter().enumerate() {
            let _ = write!(message, "\n  [{i}] {}", describe_info(info));
        }
        let _ = write!(
            message,
            "\nchoose one with {ADAPTER_ENV}=<name part or index> (and {BACKEND_ENV}=<backend>)"
        );
    }
    message
}

/// `name [Backend, DeviceType, driver: driver driver_info]`.
fn describe_info(info: &wgpu::AdapterInfo) -> String {
    let driver = [info.driver.trim(), info.driver_info.trim()]
        .into_iter()
        .filter(|s| !s.is_empty())
        .collect::<Vec<_>>()
        .join(" ");
    let name = if info.name.is_empty() {
        "unnamed adapter"
    } else {
        info.name.as_str()
    };
    if driver.is_empty() {
        format!("{name} [{:?}, {:?}]", info.backend, info.device_type)
    } else {
        format!(
            "{name} [{:?}, {:?}, driver: {driver}]",
            info.backend, info.device_type
        )
    }
}

/// `kind: description` for a wgpu error (its description already holds the cause chain).
fn describe_wgpu_error(error: &wgpu::Error) -> String {
    match error {
        wgpu::Error::OutOfMemory { source } => format!("out of GPU memory: {source}"),
        wgpu::Error::Validation { description, .. } => {
            format!("validation error: {}", tidy_description(description))
        }
        wgpu::Error::Internal { description, .. } => {
            format!("internal error: {}", tidy_description(description))
        }
    }
}

/// wgpu-core's descriptions read "Validation Error\n\nCaused by:\n  In Device::...\n
/// <details>"; drop the generic header and the indentation, keep the lines (shader
/// compilation errors carry a source excerpt that needs them).
fn tidy_description(description: &str) -> String {
    let mut lines: Vec<&str> = description.trim_end().lines().collect();
    let header = lines.iter().position(|l| l.trim() == "Caused by:");
    if let Some(i) = header {
        if lines[..i]
            .iter()
            .all(|l| l.trim().is_empty() || l.trim().ends_with("Error"))
        {
            lines.drain(..=i);
        }
    }
    let indent = lines
        .iter()
        .filter(|l| !l.trim().is_empty())
        .map(|l| l.len() - l.trim_start().len())
        .min()
        .unwrap_or(0);
    lines
        .iter()
        .map(|l| l.get(indent..).unwrap_or(l.trim_start()))
        .collect::<Vec<_>>()
        .join("\n")
}

/// An error and its causes, `a: b: c`.
fn error_chain(error: &dyn std::error::Error) -> String {
    let mut message = error.to_string();
    let mut cause = error.source();
    while let Some(c) = cause {
        let text = c.to_string();
        if !message.contains(&text) {
            let _ = write!(message, ": {text}");
        }
        cause = c.source();
    }
    message
}
