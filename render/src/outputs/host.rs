//! How much more memory this process may take: the least of what the machine has available and
//! what the process's own limits leave. Comparing an estimate with the machine's free memory
//! alone lets a run under `ulimit -v`, `prlimit` or a container's cgroup start, compute for
//! minutes and then die on an allocation that names nothing (or crash inside a driver).

use std::path::{Path, PathBuf};

use nix::sys::resource::{Resource, getrlimit};

/// What bounds the memory a run may still take, and how much that is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HostMemory {
    pub bytes: u64,
    /// The limit that binds, in words (`its address-space limit (RLIMIT_AS, ulimit -v)`).
    pub bound: &'static str,
}

/// What the process may still take: memory, and address space (which a driver's mappings and
/// thread stacks take without using much memory).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Budget {
    /// The least of: the machine's `MemAvailable`, `RLIMIT_AS` minus the address space in use,
    /// `RLIMIT_DATA` minus the data in use, and each enclosing cgroup v2's `memory.max` minus
    /// its `memory.current`.
    pub memory: Option<HostMemory>,
    /// `RLIMIT_AS` minus the address space in use.
    pub address_space: Option<HostMemory>,
}

/// This process's budget now (Linux; elsewhere no limit is known and no check is made).
pub fn budget() -> Budget {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let left = |limit: Option<u64>, field: &str| Some(limit?.saturating_sub(status_kib(&status, field)? * 1024));
    let address_space = (
        left(soft_limit(Resource::RLIMIT_AS), "VmSize:"),
        "what its address-space limit leaves (RLIMIT_AS, ulimit -v)",
    );
    Budget {
        memory: least([
            (mem_available(), "the machine's available memory (MemAvailable)"),
            address_space,
            (
                left(soft_limit(Resource::RLIMIT_DATA), "VmData:"),
                "what its data-size limit leaves (RLIMIT_DATA, ulimit -d)",
            ),
            (cgroup_left(), "what its cgroup's memory.max leaves"),
        ]),
        address_space: least([address_space]),
    }
}

/// The smallest of the known amounts.
fn least<const N: usize>(candidates: [(Option<u64>, &'static str); N]) -> Option<HostMemory> {
    candidates
        .into_iter()
        .filter_map(|(bytes, bound)| Some(HostMemory { bytes: bytes?, bound }))
        .min_by_key(|m| m.bytes)
}

/// A soft resource limit, None when unlimited.
fn soft_limit(resource: Resource) -> Option<u64> {
    let (soft, _) = getrlimit(resource).ok()?;
    (soft != nix::sys::resource::RLIM_INFINITY).then_some(soft)
}

fn mem_available() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    Some(status_kib(&info, "MemAvailable:")? * 1024)
}

/// The `kB` value of a `Name:  123 kB` line of /proc/meminfo or /proc/self/status.
fn status_kib(text: &str, field: &str) -> Option<u64> {
    text.lines().find_map(|l| l.strip_prefix(field))?.split_whitespace().next()?.parse().ok()
}

/// The tightest `memory.max - memory.current` of this process's cgroup v2 and its ancestors.
fn cgroup_left() -> Option<u64> {
    let membership = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let own = membership.lines().find_map(|l| l.strip_prefix("0::"))?;
    cgroup_dirs(Path::new("/sys/fs/cgroup"), own)
        .iter()
        .filter_map(|dir| {
            let read = |name: &str| std::fs::read_to_string(dir.join(name)).ok();
            let max: u64 = read("memory.max")?.trim().parse().ok()?; // "max": no limit
            let current: u64 = read("memory.current")?.trim().parse().ok()?;
            Some(max.saturating_sub(current))
        })
        .min()
}

/// The cgroup folders from the process's own up to the mount's root. In a container the
/// process's path (as the host names it) may not exist under the container's mount: then the
/// mount's root is the container's own cgroup.
fn cgroup_dirs(mount: &Path, own: &str) -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> = Path::new(own.trim())
        .ancestors()
        .map(|a| mount.join(a.strip_prefix("/").unwrap_or(a)))
        .filter(|d| d.is_dir())
        .collect();
    if dirs.is_empty() {
        dirs.push(mount.to_path_buf());
    }
    dirs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tightest_known_limit_binds() {
        let m = least([(Some(8 << 30), "free"), (None, "unlimited"), (Some(3 << 30), "address space")]);
        assert_eq!(m, Some(HostMemory { bytes: 3 << 30, bound: "address space" }));
        assert_eq!(least([(None, "unlimited")]), None);
    }

    #[test]
    fn status_fields_are_read_in_kib() {
        let status = "Name:\tparallax\nVmPeak:\t  200 kB\nVmSize:\t  123456 kB\nVmData:\t 42 kB\n";
        assert_eq!(status_kib(status, "VmSize:"), Some(123_456));
        assert_eq!(status_kib(status, "VmData:"), Some(42));
        assert_eq!(status_kib(status, "VmSwap:"), None);
    }

    #[test]
    fn this_process_has_a_budget_on_linux() {
        if cfg!(target_os = "linux") {
            assert!(budget().memory.is_some_and(|m| m.bytes > 0));
        }
    }
}
