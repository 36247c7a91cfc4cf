//! `parallax bench`'s tables: bench.md and the figures of its cells.

pub mod tables;
