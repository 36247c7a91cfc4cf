//! Progressive accumulation of a converged reference, and the partial state that makes it
//! resumable.
//!
//! Samples arrive in chunks: the GPU (or the CPU tracer) returns the f32 mean of one chunk of
//! `chunk_spp` samples per pixel, and the running sum over chunks is kept in f64, so the
//! rounding of thousands of f32 additions never enters the result (4096 spp in f32 would lose
//! about 12 of 24 mantissa bits of the last sample's contribution). Chunk `k` is traced with
//! frame index `FRAME_BASE + k`, so its random numbers depend only on `k`: a run interrupted after
//! any number of chunks and resumed adds exactly the same chunks in the same order as an
//! uninterrupted run, which makes the two bit-identical.
//!
//! The f32 EXRs of the mean are not enough to resume (the f64 sum cannot be recovered from
//! them), so the state lives in a sidecar, `reference.partial`, written atomically after every
//! chunk: magic, a JSON header (settings, sizes, spp reached), then the f64 sums and the
//! per-chunk image means, little-endian, then the FNV-1a (64 bits) of everything before it. A
//! resumed run trusts nothing it reads: the checksum, the size the header declares, header
//! values that agree (spp = chunks × chunk_spp, finite seconds) and finite, non-negative sums.

use std::collections::BTreeMap;
use std::io::{Read, Write};

use parallax_scene::input::{FNV1A_OFFSET, fnv1a, fnv1a_continue, open_regular};
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{AccuracyError, Result};

/// Frame index of chunk 0: far from the frames `render` and `trace` use (0, 1, 2, …), so a
/// reference's noise is independent of the renderings it is compared with.
pub const FRAME_BASE: u32 = 1 << 30;

/// Version 2 ends in a checksum; version 1 files are refused ("delete it to start over").
const MAGIC: &[u8; 8] = b"PLXREF02";

/// File name of the sidecar in a reference folder.
pub const PARTIAL_FILE: &str = "reference.partial";

/// Everything of a partial reference but the sums.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceHeader {
    /// What the result depends on, keyed by the command-line flag that sets it; a resumed
    /// run must match every entry.
    pub settings: BTreeMap<String, String>,
    pub views: usize,
    pub width: usize,
    pub height: usize,
    pub chunk_spp: u32,
    pub chunks: u64,
    pub spp: u64,
    /// Seconds of tracing over all runs so far.
    pub seconds: f64,
    /// Per chunk: the mean radiance (R, G, B) over every pixel of every view; their spread gives
    /// the standard error of the image mean. Stored in binary after the sums (JSON does not
    /// round-trip every f64 exactly).
    #[serde(skip)]
    pub chunk_means: Vec<[f64; 3]>,
}

/// A reference in progress: the header and the f64 radiance sums, view-major, 3 per pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct Accumulator {
    pub header: ReferenceHeader,
    sums: Vec<f64>,
}

impl Accumulator {
    pub fn new(
        settings: BTreeMap<String, String>,
        views: usize,
        (width, height): (usize, usize),
        chunk_spp: u32,
    ) -> Self {
        let header = ReferenceHeader {
            settings,
            views,
            width,
            height,
            chunk_spp,
            chunks: 0,
            spp: 0,
            seconds: 0.0,
            chunk_means: Vec::new(),
        };
        Self { header, sums: vec![0.0; views * width * height * 3] }
    }

    /// The frame index chunk `chunks` (the next one) is traced with.
    pub fn next_frame(&self) -> u32 {
        FRAME_BASE.wrapping_add(self.header.chunks as u32)
    }

    /// Adds one chunk: per view, the f32 mean radiance of `chunk_spp` samples per pixel.
    pub fn add_chunk(&mut self, views: &[Vec<[f32; 3]>], seconds: f64) {
        let h = &mut self.header;
        let n = h.width * h.height;
        assert!(views.len() == h.views && views.iter().all(|v| v.len() == n), "chunk of the wrong shape");
        let weight = h.chunk_spp as f64;
        let mut mean = [0.0f64; 3];
        for (v, pixels) in views.iter().enumerate() {
            for (i, p) in pixels.iter().enumerate() {
                for c in 0..3 {
                    self.sums[(v * n + i) * 3 + c] += p[c] as f64 * weight;
                    mean[c] += p[c] as f64;
                }
            }
        }
        h.chunk_means.push(mean.map(|m| m / (n * h.views).max(1) as f64));
        h.chunks += 1;
        h.spp += u64::from(h.chunk_spp);
        h.seconds += seconds;
    }

    /// View `v`'s mean radiance so far (zero before the first chunk).
    pub fn mean(&self, v: usize) -> Vec<[f32; 3]> {
        let n = self.header.width * self.header.height;
        let spp = self.header.spp.max(1) as f64;
        self.sums[v * n * 3..(v + 1) * n * 3].chunks(3).map(|s| [0, 1, 2].map(|c| (s[c] / spp) as f32)).collect()
    }

    /// Mean radiance over all pixels of all views and its standard error, per channel, from the
    /// spread of the per-chunk means (chunks are independent and identically distributed).
    pub fn mean_and_standard_error(&self) -> ([f64; 3], [f64; 3]) {
        let m = &self.header.chunk_means;
        let k = m.len() as f64;
        let mean = [0, 1, 2].map(|c| m.iter().map(|x| x[c]).sum::<f64>() / k.max(1.0));
        let se = [0, 1, 2].map(|c| {
            if m.len() < 2 {
                return f64::INFINITY;
            }
            let var = m.iter().map(|x| (x[c] - mean[c]).powi(2)).sum::<f64>() / (k - 1.0);
            (var / k).sqrt()
        });
        (mean, se)
    }

    /// Fails with [`AccuracyError::SettingsDiffer`], naming every flag that differs, unless
    /// this partial state was made with `settings`.
    pub fn check_settings(&self, given: &BTreeMap<String, String>, path: &Path) -> Result<()> {
        let keys: std::collections::BTreeSet<&String> = self.header.settings.keys().chain(given.keys()).collect();
        let unset = || "(unset)".to_string();
        let differences: Vec<String> = keys
            .into_iter()
            .filter(|key| self.header.settings.get(*key) != given.get(*key))
            .map(|key| {
                let stored = self.header.settings.get(key).cloned().unwrap_or_else(unset);
                let now = given.get(key).cloned().unwrap_or_else(unset);
                format!("{key} {stored} (this run: {key} {now})")
            })
            .collect();
        if differences.is_empty() {
            return Ok(());
        }
        Err(AccuracyError::SettingsDiffer { path: path.into(), differences: differences.join("; ") })
    }

    /// Writes the sidecar atomically (temporary file in the same folder, then a rename).
    pub fn save(&self, path: &Path) -> Result<()> {
        let header = serde_json::to_vec(&self.header).expect("header serialises");
        let mut bytes = Vec::with_capacity(16 + header.len() + self.sums.len() * 8);
        bytes.extend_from_slice(MAGIC);
        bytes.extend_from_slice(&(header.len() as u64).to_le_bytes());
        bytes.extend_from_slice(&header);
        for s in self.sums.iter().chain(self.header.chunk_means.iter().flatten()) {
            bytes.extend_from_slice(&s.to_le_bytes());
        }
        let checksum = fnv1a(&bytes);
        bytes.extend_from_slice(&checksum.to_le_bytes());
        write_atomically(path, |f| f.write_all(&bytes))
    }

    /// Reads a sidecar written by [`Accumulator::save`]: a regular file, its header first (at
    /// most [`MAX_HEADER_BYTES`]), then exactly the sums the header declares, never more.
    pub fn load(path: &Path) -> Result<Self> {
        let bad = |detail: &str| AccuracyError::BadInput {
            path: path.into(),
            detail: format!("{detail}: not a partial reference of this version; delete it to start over"),
        };
        let read_err = |e: std::io::Error| AccuracyError::Read { path: path.into(), detail: e.to_string() };
        let (mut file, size) = open_regular(path)?;
        let mut start = [0u8; 16];
        if size < 16 || file.read_exact(&mut start).is_err() || &start[..8] != MAGIC {
            return Err(bad("bad magic"));
        }
        let len = u64::from_le_bytes(start[8..16].try_into().expect("8 bytes"));
        if len > MAX_HEADER_BYTES || 16 + len > size {
            return Err(bad("truncated header"));
        }
        let mut header_bytes = vec![0u8; len as usize];
        file.read_exact(&mut header_bytes).map_err(read_err)?;
        let mut header: ReferenceHeader =
            serde_json::from_slice(&header_bytes).map_err(|e| bad(&format!("bad header ({e})")))?;
        let count = header
            .views
            .checked_mul(header.width)
            .and_then(|n| n.checked_mul(header.height))
            .and_then(|n| n.checked_mul(3));
        let declared = count
            .and_then(|c| c.checked_add(usize::try_from(header.chunks).ok()?.checked_mul(3)?))
            .and_then(|values| values.checked_mul(8));
        let (Some(count), Some(declared)) = (count, declared) else { return Err(bad("sum data of the wrong length")) };
        if size - 16 - len != declared as u64 + 8 {
            return Err(bad("sum data of the wrong length"));
        }
        let mut data = Vec::with_capacity(declared + 8);
        file.take(declared as u64 + 8).read_to_end(&mut data).map_err(read_err)?;
        if data.len() != declared + 8 {
            return Err(bad("sum data of the wrong length"));
        }
        let stored = u64::from_le_bytes(data[declared..].try_into().expect("8 bytes"));
        let computed =
            [&start[..], &header_bytes, &data[..declared]].iter().fold(FNV1A_OFFSET, |h, part| fnv1a_continue(h, part));
        if stored != computed {
            return Err(AccuracyError::BadInput {
                path: path.into(),
                detail:
                    "its checksum does not match its contents (the file was edited or damaged); delete it to start over"
                        .into(),
            });
        }
        check_header(&header).map_err(|e| AccuracyError::BadInput {
            path: path.into(),
            detail: format!("{e}; delete it to start over"),
        })?;
        let mut values = data[..declared].chunks_exact(8).map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")));
        let sums = values.by_ref().take(count).collect();
        header.chunk_means =
            (0..header.chunks).map(|_| [0; 3].map(|_| values.next().expect("length checked"))).collect();
        let acc = Self { header, sums };
        if let Some(bad_value) =
            acc.sums.iter().chain(acc.header.chunk_means.iter().flatten()).find(|v| !(v.is_finite() && **v >= 0.0))
        {
            return Err(AccuracyError::BadInput {
                path: path.into(),
                detail: format!(
                    "it holds a radiance sum of {bad_value}, not a finite non-negative number; delete it to start over"
                ),
            });
        }
        Ok(acc)
    }
}

/// Header values that agree with each other: what a checksum cannot vouch for if the file was
/// rewritten whole by something else.
fn check_header(h: &ReferenceHeader) -> std::result::Result<(), String> {
    if h.views == 0 || h.width == 0 || h.height == 0 || h.chunk_spp == 0 {
        return Err(format!(
            "its header has {} views of {}x{} in chunks of {} spp",
            h.views, h.width, h.height, h.chunk_spp
        ));
    }
    if h.chunks.checked_mul(u64::from(h.chunk_spp)) != Some(h.spp) {
        return Err(format!("its header says {} spp from {} chunk(s) of {} spp", h.spp, h.chunks, h.chunk_spp));
    }
    if !(h.seconds.is_finite() && h.seconds >= 0.0 && h.seconds <= 1e9) {
        return Err(format!("its header says {} seconds of tracing", h.seconds));
    }
    Ok(())
}

/// The largest JSON header a partial reference may have (its settings are a few lines).
pub const MAX_HEADER_BYTES: u64 = 1 << 20;

/// Prefix of the temporary files of [`write_atomically`]; a killed process can leave them
/// behind, and [`remove_stale_temporaries`] clears them.
pub const TEMP_PREFIX: &str = ".parallax-tmp-";

fn temporary_in(dir: &Path) -> std::io::Result<tempfile::NamedTempFile> {
    tempfile::Builder::new().prefix(TEMP_PREFIX).tempfile_in(dir)
}

/// Removes the temporary files a killed writer left in `dir` (only ours, by their prefix).
pub fn remove_stale_temporaries(dir: &Path) {
    for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        if entry.file_name().to_string_lossy().starts_with(TEMP_PREFIX) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// Why a file could not be written in `folder`, in words: the folder is gone (moved or removed
/// while the run went on, which the OS reports as a missing file), or the OS's own reason,
/// without the Debug-quoted path (`at path "…"`) that tempfile adds to it.
pub fn write_failure(folder: &Path, error: &std::io::Error) -> String {
    if !folder.is_dir() {
        return folder_gone(folder);
    }
    let mut cause: &dyn std::error::Error = error;
    while let Some(inner) = cause.source() {
        cause = inner;
    }
    cause.to_string()
}

/// What to say of an output folder that is not there any more.
pub fn folder_gone(folder: &Path) -> String {
    format!(
        "folder {} no longer exists: it was moved or removed while the run went on; leave the output folder in place \
         until the run ends",
        folder.display()
    )
}

/// Writes `path` through a temporary file in its folder and a rename, so readers never see a
/// partial file and a failure leaves nothing behind (the temporary file is removed on drop).
pub fn write_atomically(path: &Path, write: impl FnOnce(&mut std::fs::File) -> std::io::Result<()>) -> Result<()> {
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let fail = |e: std::io::Error| AccuracyError::Write { path: path.into(), detail: write_failure(dir, &e) };
    let mut tmp = temporary_in(dir).map_err(fail)?;
    write(tmp.as_file_mut()).and_then(|_| tmp.as_file().sync_all()).map_err(fail)?;
    readable(tmp.as_file()).map_err(fail)?;
    tmp.persist(path).map_err(|e| fail(e.error))?;
    Ok(())
}

/// Like [`write_atomically`] for writers that take a path (the EXR writer): `write` fills the
/// temporary file at the path it is given.
pub fn write_atomically_to_path(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let fail = |e: std::io::Error| AccuracyError::Write { path: path.into(), detail: write_failure(dir, &e) };
    let tmp = temporary_in(dir).map_err(fail)?;
    write(tmp.path())?;
    readable(tmp.as_file()).map_err(fail)?;
    tmp.persist(path).map_err(|e| fail(e.error))?;
    Ok(())
}

/// Temporary files are created private (0600); results are ordinary files (0644).
fn readable(file: &std::fs::File) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        file.set_permissions(std::fs::Permissions::from_mode(0o644))?;
    }
    #[cfg(not(unix))]
    let _ = file;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(depth: &str) -> BTreeMap<String, String> {
        BTreeMap::from([("--max-depth".to_string(), depth.to_string()), ("--scene".to_string(), "default".to_string())])
    }

    /// f32 chunk means whose f64 sum differs from an f32 running sum (1/3 is inexact).
    fn chunk(k: u64) -> Vec<Vec<[f32; 3]>> {
        (0..2).map(|v| (0..6).map(|i| [(k + i + v) as f32 / 3.0, 0.1, 1e-3 * k as f32]).collect()).collect()
    }

    #[test]
    fn sums_in_f64_and_resumes_bit_identically() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(PARTIAL_FILE);
        let mut straight = Accumulator::new(settings("6"), 2, (3, 2), 4);
        for k in 0..6 {
            straight.add_chunk(&chunk(k), 0.5);
        }
        let mut first = Accumulator::new(settings("6"), 2, (3, 2), 4);
        for k in 0..3 {
            first.add_chunk(&chunk(k), 0.5);
        }
        first.save(&path).unwrap();
        let mut resumed = Accumulator::load(&path).unwrap();
        assert_eq!(resumed, first);
        assert_eq!(resumed.next_frame(), FRAME_BASE + 3);
        for k in 3..6 {
            resumed.add_chunk(&chunk(k), 0.5);
        }
        assert_eq!(resumed, straight);
        assert_eq!(resumed.header.spp, 24);
        // Mean of 6 chunks of (k + i + v)/3 with k = 0..5 at pixel 0 of view 0: 2.5/3.
        assert!((resumed.mean(0)[0][0] - 2.5 / 3.0).abs() < 1e-7);
        let (mean, se) = resumed.mean_and_standard_error();
        assert!((mean[1] - 0.1).abs() < 1e-7 && se[1] < 1e-7, "{mean:?} {se:?}");
        assert!(se[0] > 0.0);
    }

    #[test]
    fn resume_names_the_flag_that_differs() {
        let acc = Accumulator::new(settings("6"), 1, (1, 1), 4);
        acc.check_settings(&settings("6"), Path::new("p")).unwrap();
        let err = acc.check_settings(&settings("8"), Path::new("p")).unwrap_err();
        let text = err.to_string();
        assert!(text.contains("--max-depth 6") && text.contains("--max-depth 8"), "{text}");
    }

    #[test]
    fn a_damaged_sidecar_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(PARTIAL_FILE);
        let acc = Accumulator::new(settings("6"), 1, (2, 2), 4);
        acc.save(&path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 8]).unwrap();
        assert!(matches!(Accumulator::load(&path), Err(AccuracyError::BadInput { .. })));
        std::fs::write(&path, b"junk").unwrap();
        assert!(matches!(Accumulator::load(&path), Err(AccuracyError::BadInput { .. })));
    }

    /// An edited sum, an spp that is not chunks × chunk_spp, NaN sums or seconds of 1e308 are
    /// refused, each with what is wrong.
    #[test]
    fn an_edited_sidecar_is_refused_naming_what_is_wrong() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(PARTIAL_FILE);
        let detail = |acc: &Accumulator| {
            acc.save(&path).unwrap();
            match Accumulator::load(&path) {
                Err(AccuracyError::BadInput { detail, .. }) => detail,
                other => panic!("{other:?}"),
            }
        };
        let mut acc = Accumulator::new(settings("6"), 2, (3, 2), 4);
        acc.add_chunk(&chunk(1), 0.5);
        acc.save(&path).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        let last_sum = bytes.len() - 16;
        bytes[last_sum] ^= 1;
        std::fs::write(&path, &bytes).unwrap();
        assert!(
            matches!(Accumulator::load(&path), Err(AccuracyError::BadInput { detail, .. }) if detail.contains("checksum"))
        );
        let mut odd = acc.clone();
        odd.header.spp = 177;
        assert!(detail(&odd).contains("177 spp from 1 chunk(s) of 4 spp"));
        let mut slow = acc.clone();
        slow.header.seconds = 1e308;
        assert!(detail(&slow).contains("seconds of tracing"));
        let mut nan = acc.clone();
        nan.add_chunk(&vec![vec![[f32::NAN, 0.0, 0.0]; 6]; 2], 0.5);
        assert!(detail(&nan).contains("radiance sum of NaN"));
        let mut negative = acc.clone();
        negative.add_chunk(&vec![vec![[-1e5, 0.0, 0.0]; 6]; 2], 0.5);
        assert!(detail(&negative).contains("not a finite non-negative number"));
    }
}
