//! What a run will cost, estimated before anything is allocated, and refused with the numbers
//! and the flags to change when it cannot fit: an out-of-memory kill or a driver's
//! `vkBindImageMemory failed` names neither the input nor the limit.

use anyhow::{Result, bail};
use parallax_backend::Context;
use parallax_graph::Scheme;
use parallax_scene::PixelSample;

/// GPU bytes per traced pixel: the path tracer writes four RGBA32F layers (radiance,
/// albedo + roughness, normal + metallic, position + depth).
const DEVICE_BYTES_PER_PIXEL: u64 = 4 * 16;
/// Host bytes per traced pixel: the four layers read back plus the frame the outputs are
/// written from.
const HOST_BYTES_PER_PIXEL: u64 = DEVICE_BYTES_PER_PIXEL + size_of::<PixelSample>() as u64;

/// Paths (pixels × samples × views) above which a run is announced with its duration.
const WARN_PATHS: f64 = 1e10;
/// Paths above which a run is refused: more than a day even at 1e9 paths/s.
const MAX_PATHS: f64 = 1e14;
/// Throughputs the duration warning quotes: a data-centre GPU and a CPU (or lavapipe).
const FAST_PATHS_PER_S: f64 = 1e9;
const SLOW_PATHS_PER_S: f64 = 1e7;

/// Pass instances plus dependencies a plan may have: the planner keeps every one in memory and
/// the fine schemes grow as views × devices × sources.
const MAX_PLAN_ITEMS: u64 = 4_000_000;

pub fn gib(bytes: u64) -> String {
    format!("{:.1} GiB", bytes as f64 / f64::from(1 << 30))
}

/// The light field (or view) to be traced.
#[derive(Clone, Copy, Debug)]
pub struct TraceWork {
    pub views: u64,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
}

impl TraceWork {
    fn pixels(self) -> u64 {
        self.views * u64::from(self.width) * u64::from(self.height)
    }

    /// Host memory for the read-back views; refused beyond what the machine has free.
    pub fn check_host(self) -> Result<()> {
        let bytes = self.pixels() * HOST_BYTES_PER_PIXEL;
        check_host_bytes(
            &format!(
                "{} view(s) of {}x{} ({} B per pixel once read back)",
                self.views, self.width, self.height, HOST_BYTES_PER_PIXEL
            ),
            bytes,
            "lower --resolution or use fewer views (--lf)",
        )
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
                bail!(
                    "{} view(s) of {}x{} need about {} of GPU memory on device 0 ({} B per pixel), but its memory heap has {}: lower --resolution or use fewer views (--lf)",
                    self.views,
                    self.width,
                    self.height,
                    gib(bytes),
                    DEVICE_BYTES_PER_PIXEL,
                    gib(d.device_local_heap_bytes)
                );
            }
        }
        Ok(())
    }

    /// Refuses runs of more than a day; announces long ones with their expected duration.
    pub fn check_duration(self) -> Result<()> {
        let paths = self.pixels() as f64 * f64::from(self.spp);
        if paths > MAX_PATHS {
            bail!(
                "{paths:.2e} paths ({} view(s) × {}x{} × {} spp) would take {} even at {FAST_PATHS_PER_S:.0e} paths/s: lower --spp or --resolution (at most {MAX_PATHS:.0e} paths)",
                self.views,
                self.width,
                self.height,
                self.spp,
                duration(paths / FAST_PATHS_PER_S)
            );
        }
        if paths > WARN_PATHS {
            tracing::warn!(
                "{paths:.2e} paths to trace: about {} at {FAST_PATHS_PER_S:.0e} paths/s (a data-centre GPU), {} at {SLOW_PATHS_PER_S:.0e} paths/s (a CPU or lavapipe); Ctrl-C stops it and leaves no output",
                duration(paths / FAST_PATHS_PER_S),
                duration(paths / SLOW_PATHS_PER_S)
            );
        }
        Ok(())
    }
}

/// Refuses plans whose instance and dependency counts the planner could not hold.
pub fn check_plan_size(views: u64, devices: u64, sources: u64, scheme: Scheme) -> Result<()> {
    // Bounds from DESIGN.md's counting convention; passes per view are a dozen at most.
    let instances = views * 12 * if scheme == Scheme::MultiSource { 1 } else { devices };
    let deltas = match scheme {
        Scheme::MultiSource => views,
        Scheme::FineSources => sources * views.saturating_sub(sources) + devices * sources,
        Scheme::FineAll => devices * sources * views.saturating_sub(sources),
    };
    let items = instances + deltas;
    if items > MAX_PLAN_ITEMS {
        bail!(
            "--scheme {} over {views} views and {devices} devices with {sources} source(s) would be about {items} pass instances and dependencies (at most {MAX_PLAN_ITEMS}): use fewer devices, fewer views (--lf), or --scheme multi-source",
            scheme.name()
        );
    }
    Ok(())
}

/// Refuses a host allocation the machine cannot make (an abort on failed allocation would name
/// nothing).
pub fn check_host_bytes(what: &str, bytes: u64, fix: &str) -> Result<()> {
    if let Some(available) = available_host_memory()
        && bytes > available
    {
        bail!("{what} need about {} of host memory, but {} are available: {fix}", gib(bytes), gib(available));
    }
    Ok(())
}

/// `MemAvailable` of /proc/meminfo (Linux); elsewhere no check is made.
fn available_host_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
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
    fn runs_of_more_than_a_day_are_refused_with_the_flags() {
        let work = TraceWork { views: 1, width: 512, height: 512, spp: u32::MAX };
        let err = work.check_duration().unwrap_err().to_string();
        assert!(err.starts_with("1.13e15 paths (1 view(s) × 512x512 × 4294967295 spp) would take 13 days"), "{err}");
        assert!(err.ends_with("lower --spp or --resolution (at most 1e14 paths)"), "{err}");
        assert!(TraceWork { spp: 1 << 16, ..work }.check_duration().is_ok(), "1.7e10 paths: a warning only");
    }

    #[test]
    fn plans_beyond_the_planner_are_refused() {
        assert!(check_plan_size(100, 8, 8, Scheme::FineAll).is_ok());
        assert!(check_plan_size(4096, 64, 64, Scheme::MultiSource).is_ok());
        let err = check_plan_size(4096, 64, 64, Scheme::FineAll).unwrap_err().to_string();
        assert!(err.contains("about 19660800 pass instances and dependencies (at most 4000000)"), "{err}");
    }

    #[test]
    fn durations_read_naturally() {
        assert_eq!(duration(5.0), "5 s");
        assert_eq!(duration(600.0), "10 min");
        assert_eq!(duration(36_000.0), "10.0 h");
        assert_eq!(duration(864_000.0), "10 days");
    }
}
