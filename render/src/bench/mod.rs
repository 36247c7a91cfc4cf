//! `parallax bench` below its flags: the cases, each cell's bench.json entry and chart point,
//! `--resume` and the tables (bench.md and the figures of its cells).

pub mod case;
pub mod cell;
pub mod resume;
pub mod tables;
