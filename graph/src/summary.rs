//! The machine-readable summary of a schedule and its partition (`parallax plan --json`, render.json's `plan`).

use serde::Serialize;

use crate::lightfield::LightField;
use crate::partition::Partition;
use crate::schedule::Schedule;

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ScheduleSummary {
    pub layout: String,
    pub resolution: [u32; 2],
    pub views: u32,
    pub devices: u32,
    pub scheme: &'static str,
    /// How views were grouped into sets: multi-source only (the fine schemes place row bands).
    pub assign: Option<&'static str>,
    pub sources: Vec<u32>,
    /// Device of each view's set (multi-source only).
    pub set_of_view: Option<Vec<u32>>,
    pub delta_edges: usize,
    /// Mean distance between the two views of a δ-edge, in millimetres: smaller baselines
    /// mean smaller disparities and fewer holes after reprojection.
    pub mean_delta_distance_mm: f64,
    /// Copies between devices before the final gather.
    pub cross_device_copies: usize,
    pub gather_copies: usize,
    /// The cross-device copies as the transfers that move them (`Schedule::batches`): how many,
    /// and per device pair that has any, its batches, copies and bytes.
    pub copy_batches: usize,
    pub copy_batches_per_pair: Vec<PairBatches>,
    /// Bytes of all copies, gathers included.
    pub bytes_per_frame: u64,
    /// Rows (and bytes) halo reads reach beyond their instances' own rows per frame.
    pub halo_rows: u64,
    pub halo_bytes: u64,
    pub pass_instances: usize,
    pub culled_passes: usize,
    /// Pass instances per device, in device order.
    pub passes_per_device: Vec<usize>,
    /// Memory barriers per device program, in device order (`DeviceProgram::barriers`): the
    /// instances of a pass for many views between two barriers run side by side.
    pub barriers_per_device: Vec<usize>,
    /// Multi-source: whether `--sources-per-set auto` chose the sources, and per set the
    /// predicted cost of the sources and their holes (crate::source_cost); fine schemes: false
    /// and empty.
    pub sources_auto: bool,
    pub sources_prediction: Vec<crate::source_cost::SetPrediction>,
    /// How each device's ops are ordered: the batching compiled with and the one applied (the
    /// order the backend submits).
    pub op_order: crate::op_order::OpOrder,
}

/// The batches of one device pair ([`ScheduleSummary::copy_batches_per_pair`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct PairBatches {
    pub from: u32,
    pub to: u32,
    pub batches: usize,
    pub copies: usize,
    pub bytes: u64,
}

fn pair_batches(schedule: &Schedule) -> Vec<PairBatches> {
    let mut pairs: std::collections::BTreeMap<(u32, u32), PairBatches> = std::collections::BTreeMap::new();
    for b in &schedule.batches {
        let (from, to) = (b.from.0, b.to.0);
        let pair = pairs.entry((from, to)).or_insert(PairBatches { from, to, batches: 0, copies: 0, bytes: 0 });
        pair.batches += 1;
        pair.copies += b.copies.len();
        pair.bytes += b.bytes;
    }
    pairs.into_values().collect()
}

impl ScheduleSummary {
    pub fn new(lf: &LightField, plan: &Partition, schedule: &Schedule) -> Self {
        ScheduleSummary {
            layout: lf.name.clone(),
            resolution: [lf.width, lf.height],
            views: lf.len() as u32,
            devices: plan.devices,
            scheme: plan.scheme.name(),
            assign: (plan.scheme == crate::Scheme::MultiSource).then(|| plan.assign.name()),
            sources: plan.sources.iter().map(|v| v.0).collect(),
            set_of_view: plan.set_of_view().map(<[u32]>::to_vec),
            delta_edges: schedule.delta_edges.len(),
            mean_delta_distance_mm: mean_delta_distance(lf, schedule) * 1e3,
            cross_device_copies: schedule.dependency_copies().count(),
            gather_copies: schedule.gather_copies().count(),
            copy_batches: schedule.batches.len(),
            copy_batches_per_pair: pair_batches(schedule),
            bytes_per_frame: schedule.bytes_per_frame(),
            halo_rows: schedule.halo_reads().rows,
            halo_bytes: schedule.halo_reads().bytes,
            pass_instances: schedule.instances.len(),
            culled_passes: schedule.culled.len(),
            passes_per_device: schedule
                .devices
                .iter()
                .map(|p| p.ops.iter().filter(|o| matches!(o, crate::schedule::Op::Pass(_))).count())
                .collect(),
            barriers_per_device: schedule.devices.iter().map(|p| p.barriers.len()).collect(),
            sources_auto: plan.sources_auto,
            sources_prediction: plan.sources_prediction.clone(),
            op_order: schedule.op_order,
        }
    }
}

fn mean_delta_distance(lf: &LightField, schedule: &Schedule) -> f64 {
    if schedule.delta_edges.is_empty() {
        return 0.0;
    }
    let total: f64 =
        schedule.delta_edges.iter().map(|e| (lf.position(e.source) - lf.position(e.target)).length()).sum();
    total / schedule.delta_edges.len() as f64
}
