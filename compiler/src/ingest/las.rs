//! LAS and LAZ point clouds, formats.md §4.
//!
//! Uncompressed LAS (versions 1.0–1.4, point formats 0–10) is decoded here, straight from the
//! bytes; LAZ goes through the `las` crate (feature `laz`), point by point.
//!
//! Design decisions:
//! - The public header is read by the `las` crate's raw header reader and checked by its
//!   header builder (the point format must suit the version, after the upgrade `las::Reader`
//!   also makes; the record must be at least the format's length), so both paths agree on the
//!   point count, the format and the transforms. The VLRs are walked (headers only, nothing allocated) to check
//!   that they end before the point data; EVLRs hold no points and are not read, only checked
//!   not to overlap the points. Before a LAZ file goes to the `las` crate (which reads its EVLRs
//!   and allocates the lengths their headers claim), every EVLR is checked to end inside the
//!   file.
//! - Point records have a fixed size, so they are decoded directly from the byte buffer:
//!   X/Y/Z are `i32` at bytes 0/4/8 (`scale * value + offset`, as `f64`: coordinates reach
//!   10^6 m), intensity `u16` at 12, and RGB (3 × `u16`) at 20 in format 2, at 28 in formats 3
//!   and 5 (after the GPS time), at 30 in formats 7, 8 and 10 (LAS 1.4 R15 record layouts). A
//!   record longer than its format (extra bytes) is skipped past. The records are decoded in
//!   parallel with rayon's indexed `par_extend`, which writes every result at its own index,
//!   so the output is identical on 1 or N threads.
//! - Before anything is allocated, the header's point count is checked against [`Limits`] and
//!   against the bytes actually present: a truncated file is an error naming the byte offset
//!   of the first incomplete point, whatever the header claims.
//! - A file is read in blocks of [`BLOCK_BYTES`] by a reader thread while the previous block is
//!   decoded in parallel, so the point data is never held whole in memory besides the output
//!   (no memory map: the workspace forbids `unsafe`).
//! - No point can have a non-finite coordinate when `|scale| * 2^31 + |offset|` is finite on
//!   every axis (rounding is monotonic); only otherwise are the points checked one by one, and
//!   the first bad one is named.
//! - Intensity is kept as stored (`u16` → `f32`): producers scale it differently. Colour is
//!   `u16` per channel, but many writers store 8-bit values there, so when no channel exceeds
//!   255 the values are taken as they are, otherwise they are reduced to 8 bits (`>> 8`).
//!
//! Speed (`cargo run --release -p regolith-compiler --example bench_ingest`, 3 M points of
//! format 0 on the 2-core development machine): about 1.8 GB/s from memory on 1 thread and
//! 3.2 GB/s on 2; from a file in the page cache 1.6 and 2.1 GB/s. Measured in the same runs,
//! the `las` crate's reader gives 0.34 GB/s and laspy's `read` 1.3 GB/s (0.48 GB/s once the
//! scaled coordinates are arrays). Fresh output pages cost about half of the 1-thread time.

use std::fs::File;
use std::io::{BufReader, Cursor, Read, Seek, SeekFrom};
use std::path::Path;

use rayon::prelude::*;
use regolith_format::limits::Limits;

use super::types::PointCloud;
use crate::error::{IngestError, Result};

/// Points decoded per batch on the LAZ path.
const BATCH: u64 = 1 << 16;

/// Bytes of point records read from a file and decoded at a time.
pub const BLOCK_BYTES: usize = 8 << 20;

/// Records one rayon task decodes at least (keeps task overhead negligible).
const MIN_RECORDS_PER_TASK: usize = 1 << 12;

/// Size of a VLR header: reserved (2), user ID (16), record ID (2), length (2), description (32).
const VLR_HEADER_BYTES: u64 = 54;

fn las_err(e: las::Error) -> IngestError {
    IngestError::invalid(format!("LAS: {e}"))
}

/// Where the fields of one point record are, and how to scale them.
#[derive(Debug, Clone, Copy)]
struct Layout {
    /// Points the header announces.
    n: u64,
    /// Byte offset of the first point record.
    data_start: u64,
    /// Bytes per record (the format's length plus extra bytes).
    record_len: usize,
    /// Byte offset of the RGB triple inside a record, when the format has colour.
    rgb_at: Option<usize>,
    /// X/Y/Z scale factors.
    scale: [f64; 3],
    /// X/Y/Z offsets.
    offset: [f64; 3],
}

impl Layout {
    /// Bytes of point data the header announces.
    fn data_bytes(&self) -> u64 {
        self.n.saturating_mul(self.record_len as u64)
    }

    /// Checks the announced points against the limits and the `len` bytes present; returns the
    /// byte length of the point data.
    fn check_data(&self, len: u64, limits: &Limits) -> Result<usize> {
        Limits::check_len("points", self.n, limits.max_points)?;
        let end = self.data_start.saturating_add(self.data_bytes());
        if len >= end {
            return usize::try_from(self.data_bytes()).map_err(|_| {
                IngestError::invalid("LAS: the point data does not fit in memory on this machine")
            });
        }
        let rec = self.record_len as u64;
        if len < self.data_start {
            let msg = format!(
                "LAS: the file ends at byte {len}, before its point data (byte {})",
                self.data_start
            );
            return Err(IngestError::invalid(msg).at_offset(len));
        }
        let whole = (len - self.data_start) / rec;
        let msg = format!(
            "LAS: truncated in point {} of {}: the header announces {} points of {rec} bytes \
             from byte {}, the file ends at byte {len}",
            whole + 1,
            self.n,
            self.n,
            self.data_start
        );
        Err(IngestError::invalid(msg).at_offset(self.data_start + whole * rec))
    }
}

/// What a header announces.
enum Kind {
    /// LAZ: left to the `las` crate.
    Compressed,
    /// Uncompressed LAS with this layout.
    Plain(Layout),
}

/// Reads and checks the public header and the VLR headers of a LAS/LAZ source positioned at
/// its start; `len` is the source's length in bytes.
fn read_header<R: Read + Seek>(r: &mut R, len: u64) -> Result<Kind> {
    let raw = las::raw::Header::read_from(&mut *r).map_err(las_err)?;
    let data_start = u64::from(raw.offset_to_point_data);
    let header_size = u64::from(raw.header_size);
    let vlrs = raw.number_of_variable_length_records;
    let evlr = raw.evlr;
    let mut builder = las::Builder::new(raw).map_err(las_err)?;
    // `las::Reader` upgrades a version too old for the point format rather than failing.
    if let Some(v) = builder.minimum_supported_version() {
        if v > builder.version {
            builder.version = v;
        }
    }
    let header = builder.into_header().map_err(las_err)?;
    let format = *header.point_format();
    if format.is_compressed {
        if let Some(evlr) = evlr {
            check_evlrs(r, evlr.start_of_first_evlr, evlr.number_of_evlrs, len)?;
        }
        return Ok(Kind::Compressed);
    }
    // The VLRs follow the header and must end before the point data (as `las::Reader` checks).
    let mut at = r.stream_position()?;
    let mut end = header_size;
    for i in 0..vlrs {
        let mut h = [0u8; VLR_HEADER_BYTES as usize];
        r.read_exact(&mut h).map_err(|e| {
            let msg = format!("LAS: VLR {} of {vlrs} is cut off ({e})", i + 1);
            IngestError::invalid(msg).at_offset(at)
        })?;
        let [.., l0, l1] = *h.first_chunk::<22>().unwrap_or(&[0; 22]);
        let size = VLR_HEADER_BYTES + u64::from(u16::from_le_bytes([l0, l1]));
        at += size;
        end += size;
        if at > len {
            let msg = format!("LAS: VLR {} of {vlrs} runs past the end of the file", i + 1);
            return Err(IngestError::invalid(msg).at_offset(at - size));
        }
        if end > data_start {
            break;
        }
        r.seek(SeekFrom::Start(at))?;
    }
    if end > data_start {
        let msg = format!(
            "LAS: the header and VLRs end at byte {end}, after the start of the point data \
             (byte {data_start})"
        );
        return Err(IngestError::invalid(msg));
    }
    let t = header.transforms();
    let layout = Layout {
        n: header.number_of_points(),
        data_start,
        record_len: usize::from(format.len()),
        rgb_at: format.has_color.then_some(if format.is_extended {
            30
        } else if format.has_gps_time {
            28
        } else {
            20
        }),
        scale: [t.x.scale, t.y.scale, t.z.scale],
        offset: [t.x.offset, t.y.offset, t.z.offset],
    };
    if let Some(evlr) = evlr {
        let points_end = data_start.saturating_add(layout.data_bytes());
        if evlr.start_of_first_evlr < points_end {
            let msg = format!(
                "LAS: the EVLRs start at byte {}, inside the point data \
                 (bytes {data_start}..{points_end})",
                evlr.start_of_first_evlr
            );
            return Err(IngestError::invalid(msg));
        }
    }
    Ok(Kind::Plain(layout))
}

/// Bytes of an extended VLR header (LAS 1.4 R15 §2.7).
const EVLR_HEADER_BYTES: u64 = 60;

/// Checks that every extended VLR announced at `start` lies inside the `len` bytes of the
/// source. The `las` crate reads the EVLRs of a LAZ file and allocates whatever length their
/// headers claim, so a corrupt length would exhaust memory instead of giving an error.
fn check_evlrs<R: Read + Seek>(r: &mut R, start: u64, count: u32, len: u64) -> Result<()> {
    let mut at = start;
    for i in 0..count {
        let cut = || {
            let msg = format!(
                "LAS: extended VLR {} of {count} runs past the end of the file",
                i + 1
            );
            IngestError::invalid(msg).at_offset(at)
        };
        if at.checked_add(EVLR_HEADER_BYTES).is_none_or(|e| e > len) {
            return Err(cut());
        }
        r.seek(SeekFrom::Start(at))?;
        let mut h = [0u8; EVLR_HEADER_BYTES as usize];
        r.read_exact(&mut h).map_err(|_| cut())?;
        let mut l = [0u8; 8];
        l.copy_from_slice(h.get(20..28).unwrap_or(&[0; 8]));
        let end = at
            .checked_add(EVLR_HEADER_BYTES)
            .and_then(|e| e.checked_add(u64::from_le_bytes(l)));
        match end {
            Some(e) if e <= len => at = e,
            _ => return Err(cut()),
        }
    }
    r.seek(SeekFrom::Start(0))?;
    Ok(())
}

/// Decoded columns, filled block by block.
struct Columns {
    points: Vec<[f64; 3]>,
    intensity: Vec<f32>,
    rgb16: Vec<[u16; 3]>,
}

impl Columns {
    fn with_capacity(l: &Layout, limits: &Limits) -> Result<Columns> {
        Ok(Columns {
            points: limits.vec_with_capacity("points", l.n)?,
            intensity: limits.vec_with_capacity("intensities", l.n)?,
            rgb16: limits.vec_with_capacity("colours", if l.rgb_at.is_some() { l.n } else { 0 })?,
        })
    }

    /// Decodes whole records from `data` (its length is a multiple of the record length) and
    /// appends them, in order.
    fn decode(&mut self, data: &[u8], l: &Layout) {
        let (s, o) = (l.scale, l.offset);
        // Same expression as `las::Transform::direct`, so both paths give identical values.
        let head = move |r: &[u8]| -> ([f64; 3], f32) {
            match r.first_chunk::<14>() {
                Some(&[x0, x1, x2, x3, y0, y1, y2, y3, z0, z1, z2, z3, i0, i1]) => (
                    [
                        s[0] * f64::from(i32::from_le_bytes([x0, x1, x2, x3])) + o[0],
                        s[1] * f64::from(i32::from_le_bytes([y0, y1, y2, y3])) + o[1],
                        s[2] * f64::from(i32::from_le_bytes([z0, z1, z2, z3])) + o[2],
                    ],
                    f32::from(u16::from_le_bytes([i0, i1])),
                ),
                // Unreachable: every format's record is at least 20 bytes.
                None => ([f64::NAN; 3], 0.0),
            }
        };
        let records = data
            .par_chunks_exact(l.record_len)
            .with_min_len(MIN_RECORDS_PER_TASK);
        match l.rgb_at {
            None => {
                let mut cols = (
                    std::mem::take(&mut self.points),
                    std::mem::take(&mut self.intensity),
                );
                cols.par_extend(records.map(head));
                (self.points, self.intensity) = cols;
            }
            Some(at) => {
                let rgb = move |r: &[u8]| -> [u16; 3] {
                    match r.get(at..).and_then(|c| c.first_chunk::<6>()) {
                        Some(&[r0, r1, g0, g1, b0, b1]) => [
                            u16::from_le_bytes([r0, r1]),
                            u16::from_le_bytes([g0, g1]),
                            u16::from_le_bytes([b0, b1]),
                        ],
                        // Unreachable: the record length covers the format's colour.
                        None => [0; 3],
                    }
                };
                let mut cols = (
                    (
                        std::mem::take(&mut self.points),
                        std::mem::take(&mut self.intensity),
                    ),
                    std::mem::take(&mut self.rgb16),
                );
                cols.par_extend(records.map(|r| (head(r), rgb(r))));
                ((self.points, self.intensity), self.rgb16) = cols;
            }
        }
    }

    /// Checks the count and the coordinates, and reduces the colour to 8 bits.
    fn finish(self, l: &Layout, limits: &Limits) -> Result<PointCloud> {
        let Columns {
            points,
            intensity,
            rgb16,
        } = self;
        if points.len() as u64 != l.n {
            let msg = format!(
                "the header says {} points, the data has {}",
                l.n,
                points.len()
            );
            return Err(IngestError::invalid(msg));
        }
        let may_overflow = (0..3).any(|k| {
            let (s, o) = (l.scale.get(k), l.offset.get(k));
            !s.zip(o)
                .is_some_and(|(s, o)| (s.abs() * 2_147_483_648.0 + o.abs()).is_finite())
        });
        if may_overflow {
            let bad = points
                .par_iter()
                .position_first(|p| !p.iter().all(|v| v.is_finite()));
            if let Some(i) = bad {
                let msg = format!("point {} has a non-finite coordinate", i + 1);
                let at = l.data_start + i as u64 * l.record_len as u64;
                return Err(IngestError::invalid(msg).at_offset(at));
            }
        }
        let rgb = match l.rgb_at {
            None => None,
            Some(_) => {
                let shift = if rgb16.par_iter().any(|c| c.iter().any(|&v| v > 255)) {
                    8
                } else {
                    0
                };
                let mut rgb = limits.vec_with_capacity::<[u8; 3]>("colours", l.n)?;
                rgb.par_extend(rgb16.par_iter().map(|c| c.map(|v| (v >> shift) as u8)));
                Some(rgb)
            }
        };
        Ok(PointCloud {
            points,
            intensity: Some(intensity),
            rgb,
            ..Default::default()
        })
    }
}

/// Reads all points from a LAS/LAZ source with the `las` crate, point by point. This is the
/// LAZ path, and the reference the fast path is tested against.
pub fn read_las_from<R: Read + Seek + Send + Sync + 'static>(
    source: R,
    limits: &Limits,
) -> Result<PointCloud> {
    let mut reader = las::Reader::new(source).map_err(las_err)?;
    let header = reader.header();
    let n = header.number_of_points();
    Limits::check_len("points", n, limits.max_points)?;
    let has_rgb = header.point_format().has_color;
    let room = n.min(1 << 24);
    let mut points = limits.vec_with_capacity::<[f64; 3]>("points", room)?;
    let mut intensity = limits.vec_with_capacity::<f32>("intensities", room)?;
    let mut rgb16: Vec<[u16; 3]> = Vec::new();
    loop {
        let batch = reader.read_points(BATCH).map_err(las_err)?;
        if batch.is_empty() {
            break;
        }
        for p in batch.points() {
            let p = p.map_err(las_err)?;
            if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
                let msg = format!("point {} has a non-finite coordinate", points.len() + 1);
                return Err(IngestError::invalid(msg));
            }
            points.push([p.x, p.y, p.z]);
            intensity.push(f32::from(p.intensity));
            if has_rgb {
                let c = p.color.unwrap_or_default();
                rgb16.push([c.red, c.green, c.blue]);
            }
        }
    }
    if points.len() as u64 != n {
        let msg = format!("the header says {n} points, the data has {}", points.len());
        return Err(IngestError::invalid(msg));
    }
    let shift = if rgb16.iter().flatten().any(|&c| c > 255) {
        8
    } else {
        0
    };
    let rgb = has_rgb.then(|| {
        rgb16
            .iter()
            .map(|c| c.map(|v| (v >> shift) as u8))
            .collect()
    });
    Ok(PointCloud {
        points,
        intensity: Some(intensity),
        rgb,
        ..Default::default()
    })
}

/// Reads LAS/LAZ bytes (used by tests, the benchmark and the fuzz target).
pub fn read_las(bytes: &[u8], limits: &Limits) -> Result<PointCloud> {
    let len = bytes.len() as u64;
    match read_header(&mut Cursor::new(bytes), len)? {
        Kind::Compressed => read_las_from(Cursor::new(bytes.to_vec()), limits),
        Kind::Plain(l) => {
            let n_bytes = l.check_data(len, limits)?;
            let start = usize::try_from(l.data_start).unwrap_or(usize::MAX);
            let data = start
                .checked_add(n_bytes)
                .and_then(|end| bytes.get(start..end))
                .ok_or_else(|| IngestError::invalid("LAS: point data out of range"))?;
            let mut cols = Columns::with_capacity(&l, limits)?;
            cols.decode(data, &l);
            cols.finish(&l, limits)
        }
    }
}

/// Reads a LAS/LAZ file, in blocks from disk; errors name the path.
pub fn read_path(path: &Path, limits: &Limits) -> Result<PointCloud> {
    read_file(path, limits).map_err(|e| e.in_file(path))
}

fn read_file(path: &Path, limits: &Limits) -> Result<PointCloud> {
    let mut file = File::open(path)?;
    let len = file.metadata()?.len();
    let kind = read_header(&mut BufReader::new(&file), len)?;
    let l = match kind {
        Kind::Compressed => {
            file.seek(SeekFrom::Start(0))?;
            return read_las_from(BufReader::new(file), limits);
        }
        Kind::Plain(l) => l,
    };
    let total = l.check_data(len, limits)?;
    file.seek(SeekFrom::Start(l.data_start))?;
    let per_block = (BLOCK_BYTES / l.record_len).max(1) * l.record_len;
    // A reader thread fills one block while this thread decodes the previous one; two
    // buffers go back and forth. Dropping either channel end stops the other side.
    std::thread::scope(|s| {
        let (full_tx, full_rx) = std::sync::mpsc::sync_channel::<Result<Vec<u8>>>(1);
        let (empty_tx, empty_rx) = std::sync::mpsc::channel::<Vec<u8>>();
        s.spawn(move || {
            let mut done = 0usize;
            while done < total {
                let Ok(mut buf) = empty_rx.recv() else { return };
                buf.resize(per_block.min(total - done), 0);
                let block = file.read_exact(&mut buf).map(|()| buf).map_err(|e| {
                    let msg = format!("LAS: reading the point data failed ({e})");
                    IngestError::invalid(msg).at_offset(l.data_start + done as u64)
                });
                done += per_block;
                let failed = block.is_err();
                if full_tx.send(block).is_err() || failed {
                    return;
                }
            }
        });
        let mut cols = Columns::with_capacity(&l, limits)?;
        for _ in 0..2 {
            let _ = empty_tx.send(Vec::new());
        }
        let mut done = 0usize;
        while done < total {
            let buf = full_rx
                .recv()
                .map_err(|_| IngestError::invalid("LAS: the block reader stopped"))??;
            cols.decode(&buf, &l);
            done += buf.len();
            let _ = empty_tx.send(buf);
        }
        cols.finish(&l, limits)
    })
}
