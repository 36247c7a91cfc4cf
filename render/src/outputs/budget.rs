//! What a run will cost, estimated before anything is allocated, and refused with the numbers
//! and the flags to change when it cannot fit: an out-of-memory kill or a driver's
//! `vkBindImageMemory failed` names neither the input nor the limit.

use std::collections::BTreeMap;

use anyhow::{Result, bail};
use parallax_backend::{Context, DeviceSelection};
use parallax_graph::Scheme;
use parallax_scene::PixelSample;

/// GPU bytes per traced pixel: the path tracer writes four RGBA32F layers (radiance,
/// albedo + roughness, normal + metallic, position + depth).
const DEVICE_BYTES_PER_PIXEL: u64 = 4 * 16;
/// Host bytes per traced pixel: the four layers read back plus the frame the outputs are
/// written from.
const HOST_BYTES_PER_PIXEL: u64 = DEVICE_BYTES_PER_PIXEL + size_of::<PixelSample>() as u64;

/// Paths (pixels × samples × views × frames) above which a run is announced with its duration.
const WARN_PATHS: f64 = 1e10;
/// Paths above which a run is refused: more than a day even at 1e9 paths/s.
const MAX_PATHS: f64 = 1e14;
/// Throughputs the duration warning quotes: a data-centre GPU and a CPU (or lavapipe).
const FAST_PATHS_PER_S: f64 = 1e9;
const SLOW_PATHS_PER_S: f64 = 1e7;

/// Address space the Vulkan loader and driver take once, and each logical device beyond its
/// threads' stacks, measured on lavapipe (2 cores) as the smallest `ulimit -v` under which
/// `render --frames 1` completes: about 2.0 GB with one logical device, 4.8 GB with eight
/// (below that lavapipe's threads fail to start and the first frame never completes, or LLVM
/// cannot map its code).
const VULKAN_BYTES: u64 = 1536 << 20;
const DEVICE_BYTES: u64 = 384 << 20;
/// lavapipe starts a rasteriser thread per CPU core for every logical device, each with a stack
/// of this size (the default `ulimit -s`).
const THREAD_STACK_BYTES: u64 = 8 << 20;

/// Pass instances, dependencies (producer-consumer edges and δ-edges) and copies a plan may
/// have: the planner keeps every one in memory.
const MAX_PLAN_ITEMS: u64 = 4_000_000;

/// Device-local memory each logical device takes beyond what its plan and scene allocate, which
/// nothing reports before it is made, so an allowance rather than a measurement: gpu-allocator
/// carves allocations out of 256 MiB blocks (its default), so a device's last block is partly
/// empty (one block here); and as much again for what the driver allocates or pads by itself
/// (descriptor pools, command buffers, query pools, pipelines' code, an image's padding beyond
/// width × height × texel size, known only once the image exists).
const UNREPORTED_BYTES_PER_DEVICE: u64 = 512 << 20;

pub fn gib(bytes: u64) -> String {
    format!("{:.1} GiB", bytes as f64 / f64::from(1 << 30))
}

/// The light field (or view) to be traced, with the flags that set each factor (for messages
/// that name every flag that contributes).
#[derive(Clone, Copy, Debug)]
pub struct TraceWork {
    /// Views of one frame.
    pub views: u64,
    /// Frames traced (warm-up included).
    pub frames: u64,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    /// Logical Vulkan devices the run opens; 0 for the CPU tracer.
    pub devices: u64,
    /// The flag that sets `views` (`--lf`, `--views`), empty when it is always 1.
    pub views_flag: &'static str,
    /// The flags that set `frames` (`--frames, --warmup`), empty when it is always 1.
    pub frames_flag: &'static str,
}

impl TraceWork {
    /// One view of `width`x`height` at `spp` (`trace`, `bench-rays`) on `devices` devices.
    pub fn one_view(width: u32, height: u32, spp: u32, devices: u64) -> Self {
        TraceWork { views: 1, frames: 1, width, height, spp, devices, views_flag: "", frames_flag: "" }
    }

    fn pixels(self) -> u64 {
        self.views * u64::from(self.width) * u64::from(self.height)
    }

    /// "4096 view(s) (--lf) × 3 frame(s) (--frames, --warmup) × 512x512 (--resolution)", with
    /// frames and spp when asked, and the flags named.
    fn factors(self, frames: bool, spp: bool) -> (String, Vec<&'static str>) {
        let mut terms = Vec::new();
        let mut flags = Vec::new();
        if !self.views_flag.is_empty() {
            terms.push(format!("{} view(s) ({})", self.views, self.views_flag));
            flags.push(self.views_flag);
        }
        if frames && !self.frames_flag.is_empty() {
            terms.push(format!("{} frame(s) ({})", self.frames, self.frames_flag));
            flags.push(self.frames_flag);
        }
        terms.push(format!("{}x{} (--resolution)", self.width, self.height));
        flags.push("--resolution");
        if spp {
            terms.push(format!("{} spp (--spp)", self.spp));
            flags.push("--spp");
        }
        (terms.join(" × "), flags)
    }

    /// Host memory for the read-back views of one frame and the Vulkan devices; refused beyond
    /// what this process may still take ([`crate::outputs::host::budget`]).
    pub fn check_host(self) -> Result<()> {
        let (factors, mut flags) = self.factors(false, false);
        let bytes = self.pixels() * HOST_BYTES_PER_PIXEL;
        let mut what = format!("{factors} read back at {HOST_BYTES_PER_PIXEL} B per pixel");
        let mut mapped = 0;
        if self.devices > 0 {
            let cores = std::thread::available_parallelism().map_or(1, |n| n.get() as u64);
            let per_device = DEVICE_BYTES + cores * THREAD_STACK_BYTES;
            mapped = VULKAN_BYTES + self.devices * per_device;
            what = format!(
                "{what}, and {} logical device(s) (--gpus/--fake-devices) at about {} MiB of address space each",
                self.devices,
                per_device >> 20
            );
            if self.devices > 1 {
                flags.push("--gpus/--fake-devices");
            }
        }
        check_host_use(&what, bytes, mapped, &format!("lower {}", or_list(&flags)))
    }

    /// Each device's image limit and memory heap. Device 0 receives every finished view, so it
    /// is checked for all of them.
    pub fn check_devices(self, context: &Context) -> Result<()> {
        let bytes = self.pixels() * DEVICE_BYTES_PER_PIXEL;
        for d in context.device_infos() {
            let max = d.max_image_dimension_2d;
            if self.width > max || self.height > max {
                bail!(
                    "--resolution {}x{} exceeds device {} ({})'s image limit of {max} pixels per side: use at most {max}x{max}",
                    self.width,
                    self.height,
                    d.index,
                    d.name
                );
            }
            if d.index == 0 && bytes > d.device_local_heap_bytes {
                let (factors, flags) = self.factors(false, false);
                bail!(
                    "{factors} need about {} of GPU memory on device 0 ({} B per pixel), but its memory heap has {}: lower {}",
                    gib(bytes),
                    DEVICE_BYTES_PER_PIXEL,
                    gib(d.device_local_heap_bytes),
                    or_list(&flags)
                );
            }
        }
        Ok(())
    }

    /// Refuses a plan whose logical devices would allocate more than the device-local heap of
    /// the physical GPU behind them: the devices of one GPU (`--fake-devices`) add up, each GPU
    /// is checked against its own heap, and every GPU that would overflow is named at once.
    pub fn check_gpu_memory(self, spread: SchemeOnDevices, devices: &[DeviceMemory]) -> Result<()> {
        let mut by_gpu: BTreeMap<usize, Vec<&DeviceMemory>> = BTreeMap::new();
        for device in devices {
            by_gpu.entry(device.physical_index).or_default().push(device);
        }
        let overfull: Vec<Vec<&DeviceMemory>> =
            by_gpu.into_values().filter(|on_gpu| gpu_bytes(on_gpu) > on_gpu[0].heap_bytes).collect();
        if overfull.is_empty() {
            return Ok(());
        }
        let (factors, flags) = self.factors(false, false);
        let gpus: Vec<String> = overfull.iter().map(|on_gpu| overfull_gpu(on_gpu)).collect();
        let lower = format!("lower {}", or_list(&flags));
        let fix = if spread.scheme == Scheme::MultiSource {
            lower
        } else {
            // Under the fine schemes a device holds whole images of every view it has a band of,
            // so each logical device more on a GPU adds about a copy of the light field there.
            let shared = overfull.iter().any(|on_gpu| on_gpu.len() > 1);
            let fewer = format!("fewer logical devices per GPU ({}) or ", spread.selection_flag());
            format!("use {}--scheme multi-source, or {lower}", if shared { fewer.as_str() } else { "" })
        };
        bail!(
            "--scheme {} over {} logical device(s) ({} {}) with {factors} does not fit in GPU memory: {}: {fix}",
            spread.scheme.name(),
            devices.len(),
            spread.selection_flag(),
            spread.selection.count(),
            gpus.join("; ")
        );
    }

    /// Refuses runs of more than a day; announces long ones with their expected duration.
    pub fn check_duration(self) -> Result<()> {
        let paths = self.pixels() as f64 * self.frames as f64 * f64::from(self.spp);
        let (factors, flags) = self.factors(true, true);
        if paths > MAX_PATHS {
            bail!(
                "{paths:.2e} paths ({factors}) would take {} even at {FAST_PATHS_PER_S:.0e} paths/s: lower {} (at most {MAX_PATHS:.0e} paths)",
                duration(paths / FAST_PATHS_PER_S),
                or_list(&flags)
            );
        }
        if paths > WARN_PATHS {
            tracing::warn!(
                "{paths:.2e} paths to trace ({factors}): about {} at {FAST_PATHS_PER_S:.0e} paths/s (a data-centre GPU), {} at {SLOW_PATHS_PER_S:.0e} paths/s (a CPU or lavapipe); Ctrl-C stops it and leaves no output",
                duration(paths / FAST_PATHS_PER_S),
                duration(paths / SLOW_PATHS_PER_S)
            );
        }
        Ok(())
    }
}

/// Refuses a run for every limit it exceeds at once, in one line: a user who lowers the flags
/// one refusal names should not meet the next limit only on the next try. One exceeded limit
/// keeps its own message.
pub fn refuse_every_exceeded(checks: impl IntoIterator<Item = Result<()>>) -> Result<()> {
    let exceeded: Vec<String> = checks.into_iter().filter_map(|check| check.err()).map(|e| format!("{e:#}")).collect();
    match exceeded.as_slice() {
        [] => Ok(()),
        [one] => bail!("{one}"),
        several => {
            let listed: Vec<String> = several.iter().enumerate().map(|(i, e)| format!("({}) {e}", i + 1)).collect();
            bail!("{} limits exceeded: {}", several.len(), listed.join("; "))
        }
    }
}

/// How a plan is spread over devices: the flags that decide how many copies of its images the
/// devices hold.
#[derive(Clone, Copy, Debug)]
pub struct SchemeOnDevices {
    pub scheme: Scheme,
    pub selection: DeviceSelection,
}

impl SchemeOnDevices {
    fn selection_flag(self) -> &'static str {
        match self.selection {
            DeviceSelection::Gpus(_) => "--gpus",
            DeviceSelection::FakeDevices(_) => "--fake-devices",
        }
    }
}

/// What one logical device of a run will allocate in device-local memory, and the physical GPU
/// (and its heap) behind it.
#[derive(Clone, Debug)]
pub struct DeviceMemory {
    /// The logical device's index in the context.
    pub device: usize,
    /// The physical GPU behind it (`DeviceInfo::physical_index`), its name and its largest
    /// device-local heap.
    pub physical_index: usize,
    pub gpu_name: String,
    pub heap_bytes: u64,
    /// Its plan's allocations and device staging, and the scene uploaded to it.
    pub bytes: u64,
}

/// Device-local bytes the logical devices `on_gpu` of one GPU would take together.
fn gpu_bytes(on_gpu: &[&DeviceMemory]) -> u64 {
    on_gpu.iter().map(|d| d.bytes + UNREPORTED_BYTES_PER_DEVICE).sum()
}

/// "physical GPU 0 (name) would hold about X for device(s) 0, 1 (each one's bytes, and the
/// allowance each), but its memory heap has Y".
fn overfull_gpu(on_gpu: &[&DeviceMemory]) -> String {
    let first = on_gpu[0];
    let indices: Vec<String> = on_gpu.iter().map(|d| d.device.to_string()).collect();
    let each: Vec<String> = on_gpu.iter().map(|d| gib(d.bytes)).collect();
    format!(
        "physical GPU {} ({}) would hold about {} for device(s) {} ({} of plan and scene, and {} each that the \
         driver and allocator take unreported), but its memory heap has {}",
        first.physical_index,
        first.gpu_name,
        gib(gpu_bytes(on_gpu)),
        indices.join(", "),
        each.join(", "),
        gib(UNREPORTED_BYTES_PER_DEVICE),
        gib(first.heap_bytes)
    )
}

/// "a, b or c".
fn or_list(items: &[&str]) -> String {
    match items {
        [] => String::new(),
        [one] => one.to_string(),
        [init @ .., last] => format!("{} or {last}", init.join(", ")),
    }
}

/// How many views, devices and sources a plan has, and which flags set them.
#[derive(Clone, Copy, Debug)]
pub struct PlanShape {
    pub views: u64,
    pub devices: u64,
    pub sources: u64,
    pub scheme: Scheme,
    /// `--sources` or `--sources-per-set` when one of them set the source count.
    pub sources_flag: Option<&'static str>,
}

impl PlanShape {
    /// Pass instances, producer-consumer edges, δ-edges and copies of the standard pipeline's
    /// plan, bounded from above (M views, N devices, k sources, T = M - k targets; the bounds
    /// are checked against compiled plans by `plan_items_bound_the_compiled_plans`):
    /// - a view has 14 pass instances and 37 edges among them (firefly suppression's two
    ///   passes and hole filling's read of the G-buffer's `first_hit` included); under fine-all every pass is split in N bands: a band that reads
    ///   its own rows or a halo around them depends on the few bands that wrote those (64·N
    ///   edges), one that reads a whole image (SVGF's history through motion, two images) on
    ///   all N bands that wrote it: 8·N² edges and up to 6·N² copies per view;
    /// - a target reads three images of each of its sources (one source under multi-source,
    ///   all k under the fine schemes): under fine-all every band of them from every band,
    ///   3·N²·k·T edges; under fine-sources the N bands of one image and two whole ones of each source,
    ///   (N + 2)·k·T;
    /// - fine-sources splits the k sources' path tracing in N bands: 2·k·N more instances,
    ///   3·k·N more edges and k·N band copies.
    pub fn items(self) -> u64 {
        let (m, n, k) = (self.views, self.devices, self.sources);
        let t = m.saturating_sub(k);
        let (instances, edges, deltas, copies) = match self.scheme {
            Scheme::MultiSource => (14 * m, 40 * m, m, 2 * m),
            Scheme::FineSources => {
                (14 * m + 2 * k * n, 37 * m + 3 * k * n + (n + 2) * k * t, k * t + n * k, 2 * m + k * n)
            }
            Scheme::FineAll => (14 * m * n, 64 * m * n + 8 * m * n * n + 3 * n * n * k * t, n * k * t, 6 * m * n * n),
        };
        instances + edges + deltas + copies
    }

    /// Refuses plans whose items the planner could not hold, naming every flag that grows them.
    pub fn check(self) -> Result<()> {
        let items = self.items();
        if items > MAX_PLAN_ITEMS {
            let sources = match self.sources_flag {
                Some(flag) => format!("{} source(s) ({flag})", self.sources),
                None => format!("{} source(s)", self.sources),
            };
            bail!(
                "--scheme {} over {} views (--lf) and {} devices (--gpus/--fake-devices) with {sources} would be about {items} pass instances, dependencies and copies (at most {MAX_PLAN_ITEMS}): use fewer devices, fewer views (--lf){}, or --scheme multi-source",
                self.scheme.name(),
                self.views,
                self.devices,
                if self.scheme == Scheme::FineAll { ", fewer --sources" } else { "" },
            );
        }
        Ok(())
    }
}

/// Refuses a host allocation the process cannot make (an abort on failed allocation would name
/// nothing): `what` needs `bytes`, `fix` says which flags to lower.
pub fn check_host_bytes(what: &str, bytes: u64, fix: &str) -> Result<()> {
    check_host_use(what, bytes, 0, fix)
}

/// [`check_host_bytes`] of `bytes` of memory plus `mapped` bytes of address space that use
/// little memory (a Vulkan driver's mappings, its threads' stacks): those count only against
/// an address-space limit.
fn check_host_use(what: &str, bytes: u64, mapped: u64, fix: &str) -> Result<()> {
    let budget = crate::outputs::host::budget();
    if let Some(memory) = budget.memory
        && bytes > memory.bytes
    {
        bail!(
            "{what}: about {} of host memory needed, but this process may take only {} more ({}): {fix}",
            gib(bytes),
            gib(memory.bytes),
            memory.bound
        );
    }
    if let Some(space) = budget.address_space
        && bytes + mapped > space.bytes
    {
        bail!(
            "{what}: about {} of address space needed, but this process may map only {} more ({}): {fix}",
            gib(bytes + mapped),
            gib(space.bytes),
            space.bound
        );
    }
    Ok(())
}

fn duration(seconds: f64) -> String {
    match seconds {
        s if s < 120.0 => format!("{s:.0} s"),
        s if s < 7200.0 => format!("{:.0} min", s / 60.0),
        s if s < 172_800.0 => format!("{:.1} h", s / 3600.0),
        s => format!("{:.0} days", s / 86_400.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_exceeded_limit_is_named_in_one_line() {
        assert!(refuse_every_exceeded([Ok(()), Ok(())]).is_ok());
        let one = refuse_every_exceeded([Ok(()), Err(anyhow::anyhow!("too long: lower --spp"))]).unwrap_err();
        assert_eq!(one.to_string(), "too long: lower --spp");
        let two = refuse_every_exceeded([
            Err(anyhow::anyhow!("too long: lower --spp")),
            Ok(()),
            Err(anyhow::anyhow!("no room: raise --save-every")),
        ])
        .unwrap_err();
        assert_eq!(two.to_string(), "2 limits exceeded: (1) too long: lower --spp; (2) no room: raise --save-every");
    }

    #[test]
    fn runs_of_more_than_a_day_are_refused_with_the_flags() {
        let work = TraceWork::one_view(512, 512, u32::MAX, 1);
        let err = work.check_duration().unwrap_err().to_string();
        assert!(
            err.starts_with("1.13e15 paths (512x512 (--resolution) × 4294967295 spp (--spp)) would take 13 days"),
            "{err}"
        );
        assert!(err.ends_with("lower --resolution or --spp (at most 1e14 paths)"), "{err}");
        assert!(TraceWork { spp: 1 << 16, ..work }.check_duration().is_ok(), "1.7e10 paths: a warning only");
        let frames = TraceWork {
            views: 4096,
            frames: 100_001,
            spp: 1,
            views_flag: "--lf",
            frames_flag: "--frames, --warmup",
            ..work
        };
        let err = frames.check_duration().unwrap_err().to_string();
        assert!(
            err.starts_with(
                "1.07e14 paths (4096 view(s) (--lf) × 100001 frame(s) (--frames, --warmup) × 512x512 (--resolution) × 1 spp (--spp))"
            ),
            "{err}"
        );
        assert!(err.ends_with("lower --lf, --frames, --warmup, --resolution or --spp (at most 1e14 paths)"), "{err}");
    }

    #[test]
    fn plans_beyond_the_planner_are_refused_with_their_sources() {
        let shape = |views, devices, sources, scheme| PlanShape { views, devices, sources, scheme, sources_flag: None };
        assert!(shape(100, 8, 8, Scheme::FineAll).check().is_ok());
        assert!(shape(4096, 64, 64, Scheme::MultiSource).check().is_ok());
        assert!(shape(4096, 8, 8, Scheme::FineSources).check().is_ok());
        assert!(shape(4096, 64, 64, Scheme::FineSources).check().is_err(), "17M edges");
        let explicit = PlanShape { sources_flag: Some("--sources"), ..shape(4096, 64, 2, Scheme::FineAll) };
        let err = explicit.check().unwrap_err().to_string();
        assert_eq!(
            err,
            "--scheme fine-all over 4096 views (--lf) and 64 devices (--gpus/--fake-devices) with 2 source(s) (--sources) \
             would be about 356466432 pass instances, dependencies and copies (at most 4000000): use fewer devices, fewer \
             views (--lf), fewer --sources, or --scheme multi-source"
        );
    }

    /// The bounds of [`PlanShape::items`] hold for compiled plans of the standard pipeline, and
    /// are not so loose that they refuse what the planner could hold (within 4×, or 8× for
    /// the small multi-source plans whose copies are mostly the gather).
    #[test]
    fn plan_items_bound_the_compiled_plans() {
        let cases: [(&str, u32, Option<Vec<u32>>); 6] = [
            ("16x1", 1, None),
            ("16x1", 2, None),
            ("16x1", 16, None),
            ("16x2", 4, None),
            ("32x1", 8, Some(vec![0, 9, 20])),
            ("32x1", 8, None),
        ];
        for (lf, devices, sources) in cases {
            for scheme in Scheme::ALL {
                if scheme == Scheme::MultiSource && sources.is_some() {
                    continue;
                }
                let (lf, compiled) = crate::compile::compiled(lf, (64, 64), scheme, sources.clone(), devices);
                let s = &compiled.schedule;
                let actual = (s.instances.len() + s.edges.len() + s.delta_edges.len() + s.copies.len()) as u64;
                let shape = PlanShape {
                    views: lf.len() as u64,
                    devices: u64::from(devices),
                    sources: compiled.partition.sources.len() as u64,
                    scheme,
                    sources_flag: None,
                };
                let slack = if scheme == Scheme::MultiSource { 8 } else { 4 };
                assert!(
                    actual <= shape.items() && shape.items() <= slack * actual,
                    "{} {scheme:?} {sources:?} on {devices} device(s): {actual} items, estimated {}",
                    lf.name,
                    shape.items()
                );
            }
        }
    }

    const GIB: u64 = 1 << 30;

    /// Logical device `device` on physical GPU `physical` (an 80 GiB one) holding `gib` GiB.
    fn on_gpu(device: usize, physical: usize, gib: u64) -> DeviceMemory {
        DeviceMemory {
            device,
            physical_index: physical,
            gpu_name: format!("GPU{physical}"),
            heap_bytes: 80 * GIB,
            bytes: gib * GIB,
        }
    }

    /// NELF's 72 views at 1024x1024, as `render` describes them.
    fn nelf() -> TraceWork {
        TraceWork {
            views: 72,
            views_flag: "--lf",
            frames_flag: "--frames, --warmup",
            ..TraceWork::one_view(1024, 1024, 1, 4)
        }
    }

    /// Logical devices of one GPU add up against its heap, each with the unreported allowance;
    /// the refusal names the numbers, the flags that set them and the fixes.
    #[test]
    fn logical_devices_of_one_gpu_add_up_against_its_heap() {
        let fine_all = SchemeOnDevices { scheme: Scheme::FineAll, selection: DeviceSelection::FakeDevices(4) };
        // 4 × (19 + 0.5) = 78 GiB fits in 80; 4 × (20 + 0.5) = 82 does not.
        let fits: Vec<DeviceMemory> = (0..4).map(|d| on_gpu(d, 0, 19)).collect();
        assert!(nelf().check_gpu_memory(fine_all, &fits).is_ok());
        let full: Vec<DeviceMemory> = (0..4).map(|d| on_gpu(d, 0, 20)).collect();
        let err = nelf().check_gpu_memory(fine_all, &full).unwrap_err().to_string();
        assert_eq!(
            err,
            "--scheme fine-all over 4 logical device(s) (--fake-devices 4) with 72 view(s) (--lf) × 1024x1024 \
             (--resolution) does not fit in GPU memory: physical GPU 0 (GPU0) would hold about 82.0 GiB for device(s) \
             0, 1, 2, 3 (20.0 GiB, 20.0 GiB, 20.0 GiB, 20.0 GiB of plan and scene, and 0.5 GiB each that the driver and \
             allocator take unreported), but its memory heap has 80.0 GiB: use fewer logical devices per GPU \
             (--fake-devices) or --scheme multi-source, or lower --lf or --resolution"
        );
    }

    /// Each GPU is checked against its own heap: the same bytes fit spread over two GPUs, and
    /// only the GPU that overflows is named; multi-source is told only to shrink the views.
    #[test]
    fn each_gpu_is_checked_against_its_own_heap() {
        let gpus = SchemeOnDevices { scheme: Scheme::FineAll, selection: DeviceSelection::Gpus(2) };
        let two_gpus = [on_gpu(0, 0, 40), on_gpu(1, 1, 40)];
        assert!(nelf().check_gpu_memory(gpus, &two_gpus).is_ok());
        let one_gpu = [on_gpu(0, 0, 40), on_gpu(1, 0, 40)];
        assert!(nelf().check_gpu_memory(gpus, &one_gpu).is_err(), "80 GiB and the allowance on one GPU");
        let multi = SchemeOnDevices { scheme: Scheme::MultiSource, selection: DeviceSelection::Gpus(2) };
        let err = nelf().check_gpu_memory(multi, &[on_gpu(0, 0, 40), on_gpu(1, 1, 80)]).unwrap_err().to_string();
        assert!(err.starts_with("--scheme multi-source over 2 logical device(s) (--gpus 2) with 72 view(s)"), "{err}");
        assert!(err.contains(": physical GPU 1 (GPU1) would hold about 80.5 GiB for device(s) 1 (80.0 GiB"), "{err}");
        assert!(!err.contains("physical GPU 0"), "{err}");
        assert!(err.ends_with("but its memory heap has 80.0 GiB: lower --lf or --resolution"), "{err}");
        // Both GPUs over: both named, in one line; one device a GPU needs no fewer devices per GPU.
        let err = nelf().check_gpu_memory(gpus, &[on_gpu(0, 0, 80), on_gpu(1, 1, 80)]).unwrap_err().to_string();
        assert!(err.contains("80.0 GiB; physical GPU 1 (GPU1) would hold"), "{err}");
        assert!(err.ends_with(": use --scheme multi-source, or lower --lf or --resolution"), "{err}");
    }

    #[test]
    fn durations_read_naturally() {
        assert_eq!(duration(5.0), "5 s");
        assert_eq!(duration(600.0), "10 min");
        assert_eq!(duration(36_000.0), "10.0 h");
        assert_eq!(duration(864_000.0), "10 days");
    }
}
