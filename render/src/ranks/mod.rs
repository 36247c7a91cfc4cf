//! A render over several processes (MPI ranks), the part that needs no MPI: which global
//! devices each rank drives, the part of the global execution plan a rank runs, and what it
//! sends per frame. The schedule is compiled once for every rank's devices together (device `d`
//! of the whole run is device `d - first` of the rank whose range holds it), so a view renders
//! through the same instances as in one process. Under multi-source only the gather of finished
//! views to device 0 crosses ranks, and it goes through MPI after the last frame instead of the
//! executor's copies; under a fine scheme every copy between two ranks' devices is a `remote`
//! link of the executor (parallax_backend::RemoteTransport, [`crate::ranks::mpi`]).

#[cfg(feature = "mpi")]
pub mod mpi;
pub mod view_source;

use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{Result, bail};
use parallax_backend::{DeviceProgram, ExecutionPlan, KernelPlan, Op, remote_device_id};
use parallax_graph::{CopyId, DeviceId, InstanceId, Schedule};

/// Set in a rank other than 0 of a render over several ranks: rank 0 speaks for the run, so
/// this process says nothing when mpirun ends it (it has nothing staged either).
static SILENT_RANK: AtomicBool = AtomicBool::new(false);

#[cfg(feature = "mpi")]
pub fn set_silent_rank() {
    SILENT_RANK.store(true, Ordering::Relaxed);
}

/// Whether this process speaks for the run (one process, or rank 0).
pub fn speaks_for_run() -> bool {
    !SILENT_RANK.load(Ordering::Relaxed)
}

/// How many ranks a launcher (OpenMPI's mpirun, MPICH's hydra) started this process among,
/// when its environment says (None: not started by one).
pub fn launched_ranks() -> Option<u32> {
    ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE"].iter().find_map(|v| std::env::var(v).ok()?.parse().ok())
}

/// The devices of every rank, in rank order: rank r drives the global devices
/// `first(r)..first(r) + devices[r]`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RankLayout {
    pub devices: Vec<u32>,
}

impl RankLayout {
    /// The first global device of `rank`.
    pub fn first(&self, rank: usize) -> u32 {
        self.devices[..rank].iter().sum()
    }

    /// The rank that drives global device `device`.
    pub fn rank_of(&self, device: u32) -> usize {
        (0..self.devices.len()).rfind(|&r| self.first(r) <= device).unwrap_or(0)
    }

    /// Every rank's devices together: what the schedule is compiled for.
    #[cfg(feature = "mpi")]
    pub fn total(&self) -> u32 {
        self.devices.iter().sum()
    }

    /// `ranks` ranks of `devices / ranks` devices each (`plan --ranks`).
    pub fn even(devices: u32, ranks: u32) -> Result<RankLayout> {
        if ranks == 0 || devices % ranks != 0 {
            bail!(
                "--ranks {ranks} does not divide the {devices} device(s) of --gpus/--fake-devices: every rank drives \
                 the same number of devices, so give a multiple of --ranks"
            );
        }
        Ok(RankLayout { devices: vec![devices / ranks; ranks as usize] })
    }
}

/// Whether `global` copies results between devices of different ranks that a pass reads (a
/// fine scheme's bands): then every copy between two ranks, the gathers of finished bands to
/// device 0 too, is a link between the ranks, and rank 0 holds every view after each frame.
/// Otherwise (multi-source) ranks render whole views and send them to rank 0 after the last
/// frame.
pub fn linked(global: &ExecutionPlan, layout: &RankLayout) -> bool {
    global.copies.iter().any(|c| !c.is_gather() && layout.rank_of(c.from.0) != layout.rank_of(c.to.0))
}

/// The part of `global` that `rank` runs on its devices, renumbered from 0: their passes and
/// the copies between them. Where the ranks are [`linked`], it keeps every copy with one end on
/// its devices (the other end named as a device of another process, in `global`'s order, which
/// both ends' parts share: what names a copy's messages) and the other ranks' passes (what
/// says which device wrote which band of a view), which its devices never run. Otherwise
/// gathers of finished views to device 0 from another rank's devices are left out: the view is
/// read where it was written and sent through MPI.
pub fn restrict_plan(global: &KernelPlan, layout: &RankLayout, rank: usize) -> KernelPlan {
    let (first, count) = (layout.first(rank), layout.devices[rank]);
    let local = |d: DeviceId| (first..first + count).contains(&d.0);
    let linked = linked(global, layout);
    let rename = |d: DeviceId| if local(d) { DeviceId(d.0 - first) } else { remote_device_id(count as usize, d.0) };
    let mut passes = Vec::new();
    let mut pass_of: HashMap<u32, InstanceId> = HashMap::new();
    for (i, p) in global.passes.iter().enumerate().filter(|(_, p)| linked || local(p.device)) {
        pass_of.insert(i as u32, InstanceId(passes.len() as u32));
        passes.push(parallax_backend::PassInstance { device: rename(p.device), ..p.clone() });
    }
    let mut copies = Vec::new();
    let mut copy_of: HashMap<u32, CopyId> = HashMap::new();
    let kept = |c: &parallax_backend::CrossCopy| match (local(c.from), local(c.to)) {
        (true, true) => true,
        (true, false) | (false, true) => linked,
        (false, false) => false,
    };
    for (c, copy) in global.copies.iter().enumerate().filter(|(_, c)| kept(c)) {
        copy_of.insert(c as u32, CopyId(copies.len() as u32));
        copies.push(parallax_backend::CrossCopy { from: rename(copy.from), to: rename(copy.to), ..*copy });
    }
    let devices = global.devices[first as usize..(first + count) as usize]
        .iter()
        .map(|program| {
            let mut kept = DeviceProgram { device: rename(program.device), ops: Vec::new(), barriers: Vec::new() };
            // A barrier before an op left out (another rank's copy) guards the next op kept.
            let mut guarded = false;
            for (index, &op) in program.ops.iter().enumerate() {
                guarded |= program.barriers.binary_search(&(index as u32)).is_ok();
                let renumbered = match op {
                    Op::Pass(i) => pass_of.get(&i.0).map(|&i| Op::Pass(i)),
                    Op::CopyOut(c) => copy_of.get(&c.0).map(|&c| Op::CopyOut(c)),
                    Op::Signal(c) => copy_of.get(&c.0).map(|&c| Op::Signal(c)),
                    Op::Wait(c) => copy_of.get(&c.0).map(|&c| Op::Wait(c)),
                    Op::CopyIn(c) => copy_of.get(&c.0).map(|&c| Op::CopyIn(c)),
                };
                if let Some(op) = renumbered {
                    if std::mem::take(&mut guarded) {
                        kept.barriers.push(kept.ops.len() as u32);
                    }
                    kept.ops.push(op);
                }
            }
            kept
        })
        .collect();
    let mut plan = ExecutionPlan {
        resources: global.resources.clone(),
        passes,
        copies,
        // A rank's copies are renumbered and some become remote: they travel one by one.
        batches: Vec::new(),
        devices,
        history: global.history.clone(),
    };
    // Exports are read back from device 0: only those this rank's device 0 still holds (its own
    // views, and those its other devices or linked ranks gather to it) stay exported.
    let held: BTreeSet<_> = plan.resources_of_device(DeviceId(0)).into_iter().collect();
    for (a, r) in plan.resources.iter_mut().enumerate() {
        r.exported &= held.contains(&parallax_graph::AllocId(a as u32));
    }
    KernelPlan { plan, kernels: global.kernels.clone() }
}

/// The run's number of a device that a rank's part of the plan (its devices from `first`)
/// numbers `device`: one of its own, or another rank's ([`parallax_backend::remote_device`]).
pub fn run_device(plan: &ExecutionPlan, first: u32, device: usize) -> u32 {
    parallax_backend::remote_device(plan.devices.len(), DeviceId(device as u32)).unwrap_or(first + device as u32)
}

/// The views whose passes run on `plan`'s own devices: what a rank renders.
#[cfg(feature = "mpi")]
pub fn views_of(plan: &ExecutionPlan) -> BTreeSet<u32> {
    plan.passes.iter().filter(|p| p.device.index() < plan.devices.len()).map(|p| p.view.0).collect()
}

/// What one rank of a render over several ranks runs: its place among the ranks, and the
/// transport of the links between its devices and other ranks' (when they are [`linked`]).
#[derive(Clone, Debug)]
pub struct RankPart {
    pub layout: RankLayout,
    pub rank: usize,
    pub transport: Option<std::sync::Arc<dyn parallax_backend::RemoteTransport>>,
}

/// What `plan --ranks` says of one rank.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RankShare {
    pub rank: usize,
    /// Its global devices.
    pub devices: Vec<u32>,
    pub views: Vec<u32>,
    /// Pixels of its views (one frame).
    pub pixels: u64,
    /// Bytes it sends rank 0 per frame after the last one (multi-source): its finished display
    /// views (RGBA8), and with the linear EXRs their Rgba32f radiance too. Rank 0 sends nothing,
    /// nor does any rank under a fine scheme, whose views reach rank 0 through the links.
    pub display_bytes_per_frame: u64,
    pub linear_bytes_per_frame: u64,
    /// Bytes its devices send other ranks' devices every frame through the links (a fine
    /// scheme's bands and the gathers of finished bands to rank 0).
    pub link_bytes_per_frame: u64,
}

/// Which rank runs which views of `schedule` (built into `plan`) under `layout`, and what each
/// sends per frame.
pub fn shares(schedule: &Schedule, plan: &ExecutionPlan, layout: &RankLayout, width: u32) -> Vec<RankShare> {
    let pixels_per_view = u64::from(width) * u64::from(schedule.height);
    let linked = linked(plan, layout);
    (0..layout.devices.len())
        .map(|rank| {
            let first = layout.first(rank);
            let devices: Vec<u32> = (first..first + layout.devices[rank]).collect();
            let views: BTreeSet<u32> =
                schedule.instances.iter().filter(|i| devices.contains(&i.device.0)).map(|i| i.view.0).collect();
            let sent = if rank == 0 || linked { 0 } else { views.len() as u64 * pixels_per_view };
            let link_bytes_per_frame = (0..plan.copies.len() as u32)
                .map(CopyId)
                .filter(|&c| {
                    let copy = plan.copy(c);
                    layout.rank_of(copy.from.0) == rank && layout.rank_of(copy.to.0) != rank
                })
                .map(|c| plan.copy_bytes(c))
                .sum();
            RankShare {
                rank,
                devices,
                pixels: views.len() as u64 * pixels_per_view,
                views: views.into_iter().collect(),
                display_bytes_per_frame: 4 * sent,
                linear_bytes_per_frame: 16 * sent,
                link_bytes_per_frame: if linked { link_bytes_per_frame } else { 0 },
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The execution plan `render` runs for 4×2 views of 32×24 under `scheme` on `devices`.
    fn global_plan(scheme: &str, devices: u32) -> (KernelPlan, parallax_graph::ProvenSchedule) {
        let (_, compiled) = crate::compile::compiled("4x2", (32, 24), scheme.parse().unwrap(), None, devices);
        (std::sync::Arc::unwrap_or_clone(compiled.exec), compiled.schedule)
    }

    /// Under multi-source each rank's part holds its devices' passes only, renumbered from 0,
    /// with no copy from or to another rank; the parts together hold every pass once, and
    /// `plan --ranks` names the same views per rank.
    #[test]
    fn a_rank_runs_the_passes_of_its_devices_and_nothing_crosses_ranks() {
        let (global, schedule) = global_plan("multi-source", 3);
        let layout = RankLayout { devices: vec![1, 2] };
        assert!(!linked(&global, &layout));
        let shares = shares(&schedule, &global, &layout, 32);
        assert!(shares.iter().all(|s| s.link_bytes_per_frame == 0));
        let mut passes = 0;
        for (rank, share) in shares.iter().enumerate() {
            let part = restrict_plan(&global, &layout, rank);
            // Its barriers still index its ops, in order, with the ops it left out gone.
            part.validate(layout.devices[rank] as usize).unwrap();
            assert_eq!(part.devices.len(), layout.devices[rank] as usize);
            assert!(part.passes.iter().all(|p| p.device.0 < layout.devices[rank]));
            assert!(part.copies.iter().all(|c| c.from.0 < layout.devices[rank] && c.to.0 < layout.devices[rank]));
            assert_eq!(views_in(&part), share.views);
            passes += part.passes.len();
        }
        assert_eq!(passes, global.passes.len());
        assert!(global.copies.iter().any(|c| c.is_gather()), "views gathered to device 0 in one process");
    }

    /// A fine scheme reads other devices' bands: each rank's part keeps the copies with one end
    /// on its devices, the other end named past its own devices; what one rank's part sends
    /// another is what the other's receives, in the same order (what names their messages);
    /// and rank 0 holds every view, its bands gathered from the other ranks.
    #[test]
    fn linked_ranks_keep_the_copies_between_them_in_the_same_order_on_both_ends() {
        let (global, schedule) = global_plan("fine-all", 3);
        let layout = RankLayout { devices: vec![1, 1, 1] };
        assert!(linked(&global, &layout));
        let parts: Vec<KernelPlan> = (0..3).map(|r| restrict_plan(&global, &layout, r)).collect();
        // A copy as the whole run names it: (from, to, resource, version, rows).
        let global_copy = |rank: usize, c: &parallax_backend::CrossCopy| {
            let name = |d: DeviceId| if d.0 < 1 { d.0 + layout.first(rank) } else { d.0 - 1 };
            (name(c.from), name(c.to), c.src_alloc, c.version, c.region)
        };
        for (a, b) in [(0usize, 1usize), (1, 0), (1, 2), (2, 0)] {
            let between = |part: usize| -> Vec<_> {
                parts[part]
                    .copies
                    .iter()
                    .map(|c| global_copy(part, c))
                    .filter(|&(from, to, ..)| (from as usize, to as usize) == (a, b))
                    .collect()
            };
            assert!(!between(a).is_empty(), "rank {a} sends rank {b} bands");
            assert_eq!(between(a), between(b), "rank {a} → rank {b}");
        }
        for part in &parts {
            part.validate(1).unwrap();
            assert!(part.copies.iter().all(|c| c.from.0 < 1 || c.to.0 < 1), "one end on the rank");
            assert!(part.devices[0].ops.iter().all(|op| match *op {
                Op::Pass(p) => part.pass(p).device == DeviceId(0),
                _ => true,
            }));
        }
        let exported: Vec<usize> = parts.iter().map(|p| p.resources.iter().filter(|r| r.exported).count()).collect();
        assert_eq!(exported[0], global.resources.iter().filter(|r| r.exported).count());
        let shares = shares(&schedule, &global, &layout, 32);
        assert!(shares.iter().all(|s| s.display_bytes_per_frame == 0 && s.link_bytes_per_frame > 0));
    }

    fn views_in(plan: &ExecutionPlan) -> Vec<u32> {
        plan.passes.iter().map(|p| p.view.0).collect::<BTreeSet<u32>>().into_iter().collect()
    }

    #[test]
    fn a_layout_numbers_devices_rank_after_rank() {
        let layout = RankLayout { devices: vec![1, 2, 1] };
        assert_eq!((layout.first(0), layout.first(1), layout.first(2)), (0, 1, 3));
        assert_eq!((0..4).map(|d| layout.rank_of(d)).collect::<Vec<_>>(), vec![0, 1, 1, 2]);
        #[cfg(feature = "mpi")]
        assert_eq!(layout.total(), 4);
        assert_eq!(RankLayout::even(4, 2).unwrap(), RankLayout { devices: vec![2, 2] });
        assert_eq!(
            RankLayout::even(4, 3).unwrap_err().to_string(),
            "--ranks 3 does not divide the 4 device(s) of --gpus/--fake-devices: every rank drives the same number \
             of devices, so give a multiple of --ranks"
        );
    }
}
