//! A render over several processes (MPI ranks), the part that needs no MPI: which global
//! devices each rank drives, the part of the global execution plan a rank runs, and what it
//! sends to rank 0 per frame. The schedule is compiled once for every rank's devices together
//! (device `d` of the whole run is device `d - first` of the rank whose range holds it), so a
//! view renders through the same instances as in one process; only the gather of finished
//! views to device 0 crosses ranks, and it goes through MPI instead of the executor's copies
//! ([`crate::ranks_mpi`]).

use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{Result, bail};
use parallax_backend::{ExecOp, ExecutionPlan};
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

/// Why `--scheme NAME` (a fine scheme) does not run over several ranks: the usage error of
/// `render` under mpirun and of `plan --ranks`.
pub fn fine_scheme_across_ranks(scheme: &str) -> String {
    format!(
        "--scheme {scheme} splits views in row bands over every device, which does not run across ranks yet: \
         multi-source is the scheme that runs across ranks today (use --scheme multi-source, or run {scheme} in one \
         process)"
    )
}

/// The part of `global` that runs on the global devices `first..first + count`, renumbered from
/// 0: their passes and the copies between them. Gathers of finished views to device 0 from
/// another rank's devices are left out (the view is read where it was written and sent through
/// MPI); a dependency copy between ranks is refused, as only whole views cross ranks today.
pub fn restrict_plan(global: &ExecutionPlan, first: u32, count: u32) -> Result<ExecutionPlan> {
    let local = |d: DeviceId| (first..first + count).contains(&d.0);
    let rename = |d: DeviceId| DeviceId(d.0 - first);
    if let Some(c) = global.copies.iter().find(|c| !c.gather && local(c.from) != local(c.to)) {
        bail!(
            "device {} reads what device {} wrote, and the two are on different ranks: only whole views cross ranks \
             today (--scheme multi-source)",
            c.to.0,
            c.from.0
        );
    }
    let mut passes = Vec::new();
    let mut pass_of: HashMap<u32, InstanceId> = HashMap::new();
    for (i, p) in global.passes.iter().enumerate().filter(|(_, p)| local(p.device)) {
        pass_of.insert(i as u32, InstanceId(passes.len() as u32));
        passes.push(parallax_backend::ExecPass { device: rename(p.device), ..p.clone() });
    }
    let mut copies = Vec::new();
    let mut copy_of: HashMap<u32, CopyId> = HashMap::new();
    for (c, copy) in global.copies.iter().enumerate().filter(|(_, c)| local(c.from) && local(c.to)) {
        copy_of.insert(c as u32, CopyId(copies.len() as u32));
        copies.push(parallax_backend::ExecCopy { from: rename(copy.from), to: rename(copy.to), ..*copy });
    }
    let devices = global.devices[first as usize..(first + count) as usize]
        .iter()
        .map(|ops| {
            ops.iter()
                .filter_map(|op| match *op {
                    ExecOp::Pass(i) => pass_of.get(&i.0).map(|&i| ExecOp::Pass(i)),
                    ExecOp::CopyOut(c) => copy_of.get(&c.0).map(|&c| ExecOp::CopyOut(c)),
                    ExecOp::Signal(c) => copy_of.get(&c.0).map(|&c| ExecOp::Signal(c)),
                    ExecOp::Wait(c) => copy_of.get(&c.0).map(|&c| ExecOp::Wait(c)),
                    ExecOp::CopyIn(c) => copy_of.get(&c.0).map(|&c| ExecOp::CopyIn(c)),
                })
                .collect()
        })
        .collect();
    let mut plan = ExecutionPlan {
        resources: global.resources.clone(),
        passes,
        copies,
        devices,
        history_pairs: global.history_pairs.clone(),
        kernels: global.kernels.clone(),
    };
    // Exports are read back from device 0: only those this rank's device 0 still holds (its own
    // views, and those its other devices gather to it) stay exported.
    let held: BTreeSet<_> = plan.resources_of_device(DeviceId(0)).into_iter().collect();
    for (a, r) in plan.resources.iter_mut().enumerate() {
        r.exported &= held.contains(&parallax_graph::AllocId(a as u32));
    }
    Ok(plan)
}

/// The views whose passes run on `plan`'s devices: what a rank renders.
#[cfg(feature = "mpi")]
pub fn views_of(plan: &ExecutionPlan) -> BTreeSet<u32> {
    plan.passes.iter().map(|p| p.view).collect()
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
    /// Bytes it sends rank 0 per frame: its finished display views (RGBA8), and with the
    /// linear EXRs their Rgba32f radiance too. Rank 0 sends nothing.
    pub display_bytes_per_frame: u64,
    pub linear_bytes_per_frame: u64,
}

/// Which rank runs which views of `schedule` under `layout`, and what each sends per frame.
pub fn shares(schedule: &Schedule, layout: &RankLayout, width: u32) -> Vec<RankShare> {
    let pixels_per_view = u64::from(width) * u64::from(schedule.height);
    (0..layout.devices.len())
        .map(|rank| {
            let first = layout.first(rank);
            let devices: Vec<u32> = (first..first + layout.devices[rank]).collect();
            let views: BTreeSet<u32> =
                schedule.instances.iter().filter(|i| devices.contains(&i.device.0)).map(|i| i.view.0).collect();
            let sent = if rank == 0 { 0 } else { views.len() as u64 * pixels_per_view };
            RankShare {
                rank,
                devices,
                pixels: views.len() as u64 * pixels_per_view,
                views: views.into_iter().collect(),
                display_bytes_per_frame: 4 * sent,
                linear_bytes_per_frame: 16 * sent,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use clap::{Args as _, FromArgMatches as _};

    use super::*;
    use crate::pipeline_args::PipelineArgs;
    use crate::scene_args::LayoutArgs;

    /// The execution plan `render` runs for 4×2 views of 32×24 under `scheme` on `devices`.
    fn global_plan(scheme: &str, devices: u32) -> (ExecutionPlan, Schedule) {
        let words = ["--lf", "4x2", "--resolution", "32x24", "--scheme", scheme];
        let command =
            PipelineArgs::augment_args(LayoutArgs::augment_args(clap::Command::new("t").no_binary_name(true)));
        let matches = command.try_get_matches_from(words).unwrap();
        let lf = LayoutArgs::from_arg_matches(&matches).unwrap().with_rig(parallax_graph::Rig::default()).unwrap();
        let compiled = PipelineArgs::from_arg_matches(&matches).unwrap().compile(&lf, devices, 1.0).unwrap();
        (ExecutionPlan::from_schedule(&compiled.graph, &compiled.schedule).unwrap(), compiled.schedule)
    }

    /// Under multi-source each rank's part holds its devices' passes only, renumbered from 0,
    /// with no copy from or to another rank; the parts together hold every pass once, and
    /// `plan --ranks` names the same views per rank.
    #[test]
    fn a_rank_runs_the_passes_of_its_devices_and_nothing_crosses_ranks() {
        let (global, schedule) = global_plan("multi-source", 3);
        let layout = RankLayout { devices: vec![1, 2] };
        let shares = shares(&schedule, &layout, 32);
        let mut passes = 0;
        for (rank, share) in shares.iter().enumerate() {
            let part = restrict_plan(&global, layout.first(rank), layout.devices[rank]).unwrap();
            assert_eq!(part.devices.len(), layout.devices[rank] as usize);
            assert!(part.passes.iter().all(|p| p.device.0 < layout.devices[rank]));
            assert!(part.copies.iter().all(|c| c.from.0 < layout.devices[rank] && c.to.0 < layout.devices[rank]));
            assert_eq!(views_in(&part), share.views);
            passes += part.passes.len();
        }
        assert_eq!(passes, global.passes.len());
        assert!(global.copies.iter().any(|c| c.gather), "views gathered to device 0 in one process");
    }

    /// A fine scheme reads other devices' bands: its parts cannot run apart.
    #[test]
    fn a_dependency_between_ranks_is_refused() {
        let (global, _) = global_plan("fine-all", 2);
        let refused = restrict_plan(&global, 1, 1).unwrap_err().to_string();
        assert!(
            refused.ends_with("are on different ranks: only whole views cross ranks today (--scheme multi-source)"),
            "{refused}"
        );
    }

    fn views_in(plan: &ExecutionPlan) -> Vec<u32> {
        plan.passes.iter().map(|p| p.view).collect::<BTreeSet<u32>>().into_iter().collect()
    }

    #[test]
    fn a_layout_numbers_devices_rank_after_rank() {
        let layout = RankLayout { devices: vec![1, 2, 1] };
        assert_eq!((layout.first(0), layout.first(1), layout.first(2)), (0, 1, 3));
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
