//! A leaf: how a schedule's ops are ordered ([`Batching`], [`OpOrder`]), plain data the schedule
//! holds and order.rs computes, so the schedule does not import the ordering.

use serde::Serialize;

/// The backend's default chunk size (`ExecOptions::chunk_bytes`): a copy of more bytes than this
/// (and more than one row) is cut into row bands whose transfers overlap.
pub const DEFAULT_CHUNK_BYTES: u64 = 8 << 20;

/// Which copies gather at the ends of the runs of one pass on a device.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Batching {
    /// Every copy where lowering put it: the producer's side right after the producer, the
    /// consumer's right before its first consumer. Only the copies out of a
    /// [grouped](crate::PassBuilder::grouped) pass's runs wait for the run's end.
    Off,
    /// Within a run of instances of one pass, the copies that move in one piece gather: their
    /// waits and copy-ins move up to the run's start, their copy-outs and signals down to its
    /// end, wherever no instance they pass touches what they copy. One piece is at most
    /// `chunk_bytes` (or one row): the backend's chunk size, whose larger copies travel in
    /// overlapping bands and keep their place next to producer and consumer.
    SmallCopies { chunk_bytes: u64 },
}

impl Default for Batching {
    fn default() -> Self {
        Batching::SmallCopies { chunk_bytes: DEFAULT_CHUNK_BYTES }
    }
}

impl std::fmt::Display for Batching {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            Batching::Off => write!(f, "in place"),
            Batching::SmallCopies { chunk_bytes: u64::MAX } => write!(f, "batched (every copy)"),
            Batching::SmallCopies { chunk_bytes } => write!(f, "batched (copies of at most {chunk_bytes} B)"),
        }
    }
}

/// The order a schedule's programs have: the batching asked for and the one applied.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct OpOrder {
    pub requested: Batching,
    /// [`Batching::Off`] where the batched order would make the devices wait on each other in a
    /// cycle (a run's hoisted wait for a copy whose producer needs the run's deferred output).
    pub applied: Batching,
}

impl std::fmt::Display for OpOrder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.requested == self.applied {
            write!(f, "{}", self.applied)
        } else {
            write!(f, "{} ({} would make devices wait in a cycle)", self.applied, self.requested)
        }
    }
}

impl Default for OpOrder {
    fn default() -> Self {
        OpOrder { requested: Batching::Off, applied: Batching::Off }
    }
}
