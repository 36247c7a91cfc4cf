//! Running renders as a library: the outputs a run writes (checked first, written atomically),
//! its limits and resource estimates, ranks (and MPI with the `mpi` feature), render.json's
//! parts, the pictures and viewer.html, bench's cells and tables, and path tracing alone on the
//! GPU (`trace_run`). The `parallax` command line parses flags into these and prints their
//! results.

pub mod bench;
pub mod compile;
pub mod console;
pub mod error;
pub mod job;
pub mod outputs;
pub mod ranks;
pub mod report;
pub mod scene;
pub mod settings;
pub mod trace_run;
