//! # parallax-graph
//!
//! Pure planning for Parallax, a multi-GPU light-field path tracer built as a render graph.
//! No Vulkan, no GPU: everything here runs and is tested on any machine.
//!
//! * [`LightField`]: view layouts (the paper's `multiscopic` and `nelf` presets, any W×H grid)
//!   and per-view off-axis pinhole cameras.
//! * [`assign()`] and [`source`]: views → N sets (round-robin, contiguous, compact) and one
//!   source per set by a robust Weiszfeld geometric median and its nearest view.
//! * [`Graph`]: typed per-view resource handles, passes declared once with a [`Role`] and
//!   instantiated per view; writes take `&mut` and bump versions.
//! * [`compile()`]: culling, producer edges and δ-edges derived from declared reads,
//!   deterministic topological order, placement on devices by a [`Partition`] (one of the three
//!   [`Scheme`]s), cross-device copies exactly where producer and consumer devices differ;
//!   [`compile_with`] orders each device's ops by [`CompileOptions`] (runs of one pass batched
//!   by default): the order the backend submits.
//! * [`Schedule`]: plain data, checked by [`Schedule::validate`] and drawn by
//!   [`Schedule::to_dot`]; compiling proves what it built once and returns a
//!   [`ProvenSchedule`], the only kind the backend builds a kernel plan from.
//!
//! ```
//! use parallax_graph::*;
//!
//! let lf = LightField::new("8x4".parse()?, None, Some((32, 32)), Rig::default())?;
//! let config = PartitionConfig { devices: 4, scheme: Scheme::MultiSource, assign: AssignStrategy::Compact, sources: None };
//! let plan = Partition::new(&lf, &config)?;
//! let mut graph = Graph::new(plan.topology.clone());
//! let mut radiance = graph.image("radiance", Format::Rgba32f);
//! graph.pass("trace", Role::Sources).write(&mut radiance).add();
//! graph.pass("reproject", Role::Targets).read_sources(&radiance).write(&mut radiance).add();
//! graph.export(&radiance);
//! let schedule = compile(&graph, &plan)?;
//! assert!(schedule.validate().is_ok());
//! assert_eq!(schedule.delta_edges.len(), 32 - 4); // D = M − N
//! assert_eq!(schedule.dependency_copies().count(), 0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod assign;
mod barriers;
mod batch;
mod binding;
pub mod builder;
pub mod compile;
pub mod dot;
mod dot_summary;
pub mod error;
pub mod ids;
pub mod lightfield;
mod lower;
mod op_order;
pub mod order;
pub mod partition;
mod proven;
pub mod schedule;
mod scope;
pub mod source;
pub mod source_cost;
mod storage;
pub mod summary;
pub mod validate;
mod validate_global;
mod validate_history;
mod validate_storage;

pub use assign::{AssignStrategy, Assignment, assign};
pub use barriers::place_barriers;
pub use builder::{
    Buffer, Graph, Handle, HistorySlot, Image, PassBuilder, ReadSlot, Role, SlotAccess, SourcesSlot, ViewTopology,
    WriteSlot,
};
pub use compile::{BandedPlacement, PassPlacementInfo, Placement, compile, compile_with};
pub use error::{GraphError, PartitionError, ScheduleError, UnboundSlot, ValidationReport};
pub use ids::{AllocId, BatchId, CopyId, DeviceId, FamilyId, InstanceId, PassId, Region, ResourceId, ViewId};
pub use lightfield::{LayoutSpec, LightField, Rig, ViewCamera};
pub use op_order::{Batching, DEFAULT_CHUNK_BYTES, OpOrder};
pub use order::CompileOptions;
pub use partition::{Partition, PartitionConfig, Scheme, SourcesPerSet, parse_source_list};
pub use proven::ProvenSchedule;
pub use schedule::{
    Access, Allocation, CopyBatch, CopyKind, CrossCopy, DeviceProgram, Format, HaloReads, HistoryPair, Op, Origin,
    PassInfo, PassInstance, ResourceDesc, ResourceInfo, Schedule, SlotInfo,
};
pub use summary::ScheduleSummary;
