//! `parallax bench` below its flags: the cases, `--resume` and the tables (bench.md and the
//! figures of its cells).

pub mod case;
pub mod resume;
pub mod tables;
