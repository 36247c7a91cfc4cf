//! Faults injected through `PARALLAX_FAULT`, so tests can check what a failed run leaves
//! behind: a lost device, or a rank that fails or falls silent.

use anyhow::{Result, bail};
use parallax_backend::FaultInjection;

/// `PARALLAX_FAULT=device-lost:F`: frame F's submission fails as on a lost GPU
/// (`FaultInjection::LoseDevice`), so tests can check what a failed run leaves behind.
pub(super) fn fault_from_env() -> Result<Option<FaultInjection>> {
    let Ok(value) = std::env::var("PARALLAX_FAULT") else {
        return Ok(None);
    };
    if rank_fault_from_env()?.is_some() {
        return Ok(None);
    }
    match value.strip_prefix("device-lost:").and_then(|f| f.parse().ok()) {
        Some(frame) => Ok(Some(FaultInjection::LoseDevice { frame })),
        None => bail!(
            "PARALLAX_FAULT={value}: the faults are device-lost:FRAME, rank-fails:RANK:FRAME and \
             rank-stalls:RANK:FRAME (e.g. device-lost:1); unset it"
        ),
    }
}

/// A rank's injected fault (`PARALLAX_FAULT`), for tests of a render over several ranks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum RankFault {
    /// `rank-fails:R:F`: rank R's frame F fails with an error.
    Fails { rank: usize, frame: u32 },
    /// `rank-stalls:R:F`: rank R stops answering at frame F, as a hung process would.
    Stalls { rank: usize, frame: u32 },
}

/// `PARALLAX_FAULT=rank-fails:R:F` or `rank-stalls:R:F` (None: another fault, or none).
pub(super) fn rank_fault_from_env() -> Result<Option<RankFault>> {
    let Ok(value) = std::env::var("PARALLAX_FAULT") else {
        return Ok(None);
    };
    let Some((kind, place)) = value.split_once(':').filter(|(k, _)| k.starts_with("rank-")) else {
        return Ok(None);
    };
    let parsed = place.split_once(':').and_then(|(r, f)| Some((r.parse().ok()?, f.parse().ok()?)));
    match (kind, parsed) {
        ("rank-fails", Some((rank, frame))) => Ok(Some(RankFault::Fails { rank, frame })),
        ("rank-stalls", Some((rank, frame))) => Ok(Some(RankFault::Stalls { rank, frame })),
        _ => {
            bail!("PARALLAX_FAULT={value}: a rank's fault is rank-fails:RANK:FRAME or rank-stalls:RANK:FRAME; unset it")
        }
    }
}
