//! Perfuse replay container format (`.pfrec`), format version 1.
//!
//! A recording is one header followed by a stream of self-delimiting, checksummed chunks. This module is the
//! *container* layer only: chunk payloads are opaque bytes (the simulator serialises its commands, particle
//! state, bonds and cardiovascular state into them). `docs/replay-format.md` repeats this description.
//!
//! # Byte layout
//!
//! All integers are little-endian, `f64` is IEEE-754 binary64 (little-endian bit pattern), CRC32 is the
//! IEEE 802.3 polynomial (zlib/PNG/gzip CRC, as computed by `crc32fast`).
//!
//! ```text
//! offset      size  field
//! ---------------------------------------------------------------------------------------------------
//! FILE PREFIX + HEADER
//! 0           8     magic            b"PERFUSE\0"  (50 45 52 46 55 53 45 00)
//! 8           4     format_version   u32, = 1 (FORMAT_VERSION)
//! 12          4     header_len       u32, N = byte length of the header fields (<= 16 MiB)
//! 16          N     header fields    sequence of TLV fields (below)
//! 16+N        4     header_crc       u32, CRC32 of bytes [8, 16+N) (format_version, header_len, fields)
//!
//! HEADER FIELD (TLV)
//! +0          2     tag              u16
//! +2          4     len              u32, L
//! +6          L     value
//!   tag 1  program_version  UTF-8          tag 5  scenario_text   UTF-8 (the scenario file's full text)
//!   tag 2  backend          UTF-8          tag 6  scenario_hash   u64, FNV-1a 64 of scenario_text
//!   tag 3  adapter          UTF-8          tag 7  created_unix_s  u64
//!   tag 4  scenario_name    UTF-8          tag 8  parent          optional: u64 hash_of_parent_header,
//!                                                                  f64 t_s, u64 step, then UTF-8 file name
//!   Tags 1..=7 are required, each field appears at most once. Unknown tags < 0x8000 are skipped (fields added
//!   later); an unknown tag >= 0x8000 is "must understand" and makes the reader refuse the file.
//!
//! CHUNK (repeated until the End chunk)
//! +0          1     kind             u8: 1 Commands, 2 Keyframe, 3 StateHash, 4 Note, 5 End
//! +1          1     flags            u8: bit 0 = payload is raw DEFLATE (RFC 1951); other bits must be 0
//! +2          2     seq              u16, chunk index mod 65536 (first chunk 0, End included)
//! +4          8     t_s              f64, simulation time in seconds (finite, non-decreasing)
//! +12         8     step             u64, simulation step (non-decreasing)
//! +20         4     stored_len       u32, S = payload bytes on disk (<= 1 GiB)
//! +24         4     raw_len          u32, payload bytes after decompression (= S when not compressed, <= 1 GiB)
//! +28         4     head_crc         u32, CRC32 of chunk bytes [+0, +28)
//! +32         S     payload          stored payload bytes
//! +32+S       4     frame_crc        u32, CRC32 of chunk bytes [+0, +28) followed by the payload
//!
//! END CHUNK PAYLOAD (kind 5, 48 bytes, uncompressed; t_s/step repeat the last chunk's)
//! +0   u64 chunks        number of chunks before End (all kinds, including ones a reader may not know)
//! +8   u64 commands      +16 u64 keyframes      +24 u64 state_hashes      +32 u64 notes
//! +40  u64 end_offset    byte offset of the End chunk itself
//! Readers ignore End payload bytes beyond 48 (room for e.g. a keyframe index without a version bump).
//! ```
//!
//! The chunk header carries its own CRC so that a reader can tell "the file was cut inside this chunk"
//! (header intact, payload short) from "the chunk's length field is damaged" (header CRC fails), and never
//! trusts an unverified length. The trailing CRC covers the header fields too, binding the payload to its
//! header: a payload and CRC spliced in from another chunk of the same length fails (a fuzz-found regression).
//! It skips `head_crc` on purpose: the CRC of "data + its own CRC" is a constant, so including it would let
//! the two header versions cancel out and the splice would pass again. `seq` makes a removed, duplicated or
//! reordered chunk (intact in itself, e.g. files concatenated or spliced by a tool) stop the replay right
//! where the stream stops being causal, instead of only being noticed by the End counts.
//!
//! # Chunk kinds
//!
//! * `Commands` (1): a batch of timestamped viewer commands (tool poses, fire, pause, parameter changes),
//!   written uncompressed; the simulator batches one or a few frames per chunk.
//! * `Keyframe` (2): full state for seeking (particles, bonds, cardiovascular state); DEFLATE-compressed
//!   when that saves at least 1/16 of the size.
//! * `StateHash` (3): a hash of the state, to detect replay divergence.
//! * `Note` (4): free text (annotations, warnings emitted while recording).
//! * `End` (5): written by [`RecordingWriter::finish`]; a recording without it was interrupted.
//! * Unknown kinds: 0x01..=0x7F are optional and skipped with a warning; 0x00 and 0x80..=0xFF are
//!   "must understand" and stop the replay there with a warning.
//!
//! # Compatibility rule
//!
//! `format_version` is a major version. A reader accepts versions `1..=FORMAT_VERSION` and rejects a newer
//! one with [`ReplayError::UnsupportedVersion`] ("replay it with a newer Perfuse"). Changes that old readers
//! can safely ignore do not bump it: new optional header tags (< 0x8000), new optional chunk kinds
//! (0x01..=0x7F), extra End payload bytes. Anything else (new compression flag, changed layout, a
//! must-understand tag or kind) either uses the must-understand ranges or bumps `FORMAT_VERSION`.
//!
//! # Damage policy
//!
//! * Damaged prefix/header (wrong magic, newer version, header CRC, malformed field) → [`ReplayError`]:
//!   without the header the scenario is unknown and nothing can be replayed.
//! * A damaged or truncated chunk (bad CRC, cut mid-chunk, unusable payload, wrong sequence number, time
//!   going backwards, bits this reader does not understand) → reading stops there; every chunk before it is kept and a
//!   [`ReplayWarning`] says where and why. A replay is causal: commands after a gap are meaningless.
//! * Declared lengths are capped (1 GiB per chunk by default, never beyond the bytes present) and
//!   decompression is bounded by `raw_len` (itself bounded by the DEFLATE maximum ratio), so a flipped length
//!   byte cannot allocate absurd amounts of memory.
//! * A file that ends cleanly between chunks without End, End counts that disagree, or bytes after End
//!   → all chunks are kept, with a warning.
//! * Nothing in this module panics on any input.
//!
//! # Use from the simulator
//!
//! ```text
//! let mut rec = RecordingWriter::create(path, &Header::new(version, backend, adapter, name, scenario_text))?;
//! rec.write_chunk(ChunkKind::Keyframe, t, step, &state_bytes)?;      // every N seconds; or encode_chunk on a
//! rec.write_chunk(ChunkKind::Commands, t, step, &frame_commands)?;   //   worker + write_encoded
//! rec.flush()?;                                                      // now and then: bounds what a crash loses
//! rec.finish()?;
//! let r = read_recording_file(path)?;  r.check_scenario(&text)?;  for w in &r.warnings { log::warn!("{w}") }
//! ```
#![deny(
    clippy::indexing_slicing,
    clippy::panic,
    clippy::expect_used,
    clippy::unwrap_used,
    clippy::unreachable,
    clippy::todo,
    clippy::unimplemented
)]

use std::fmt;
use std::fs::File;
use std::io::{self, BufWriter, Read, Write};
use std::path::Path;

use flate2::Compression;
use flate2::read::DeflateDecoder;
use flate2::write::DeflateEncoder;
use serde::{Deserialize, Serialize};

/// First 8 bytes of every recording.
pub const MAGIC: [u8; 8] = *b"PERFUSE\0";
/// The format version this module writes, and the newest it reads.
pub const FORMAT_VERSION: u32 = 1;
/// Conventional file extension.
pub const FILE_EXTENSION: &str = "pfrec";
/// Bytes before the header fields: magic, format_version, header_len.
pub const PREFIX_LEN: usize = 16;
/// Bytes of a chunk header (kind .. head_crc).
pub const CHUNK_HEADER_LEN: usize = 32;
/// Bytes of the CRC that follows each chunk payload.
pub const CHUNK_CRC_LEN: usize = 4;
/// Chunk flag: the payload is raw DEFLATE.
pub const FLAG_DEFLATE: u8 = 0x01;
/// Largest header (TLV fields) a writer produces and the default reader limit.
pub const MAX_HEADER_LEN: u32 = 16 << 20;
/// Largest chunk payload (stored or raw) a writer produces and the default reader limit.
pub const MAX_CHUNK_LEN: u32 = 1 << 30;
/// Minimum size of the End chunk payload.
pub const END_PAYLOAD_LEN: usize = 48;
/// DEFLATE cannot expand more than about 1032:1; a larger declared `raw_len` is corrupt.
const MAX_DEFLATE_RATIO: u64 = 1032;
/// Keyframe compression level used by [`WriterOptions::default`] (1 = fastest).
pub const DEFAULT_COMPRESSION_LEVEL: u32 = 1;
/// After a keyframe that did not compress well, this many keyframes are stored raw without trying (saves
/// ~28 ms per 6.4 MB keyframe when the state is incompressible).
const COMPRESS_BACKOFF: u32 = 8;
/// Keyframes shorter than this are not compressed by default.
pub const DEFAULT_COMPRESS_MIN_LEN: usize = 4096;

const TAG_PROGRAM_VERSION: u16 = 1;
const TAG_BACKEND: u16 = 2;
const TAG_ADAPTER: u16 = 3;
const TAG_SCENARIO_NAME: u16 = 4;
const TAG_SCENARIO_TEXT: u16 = 5;
const TAG_SCENARIO_HASH: u16 = 6;
const TAG_CREATED: u16 = 7;
const TAG_PARENT: u16 = 8;
const TAG_MUST_UNDERSTAND: u16 = 0x8000;

// ------------------------------------------------------------------------------------------------------------
// Header
// ------------------------------------------------------------------------------------------------------------

/// The recording header: everything needed to set the simulation up before the first chunk.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// Replay format version of the file (always [`FORMAT_VERSION`] when writing; the file's when reading).
    pub format_version: u32,
    /// Perfuse version that wrote the recording (e.g. `env!("CARGO_PKG_VERSION")` plus git hash).
    pub program_version: String,
    /// Compute backend (e.g. "wgpu/Vulkan", "cpu-rayon").
    pub backend: String,
    /// GPU adapter name ("" for the CPU twin).
    pub adapter: String,
    /// Scenario name (usually the scenario file's stem).
    pub scenario_name: String,
    /// The scenario file's full text, so a recording replays without the original file.
    pub scenario_text: String,
    /// [`scenario_hash`] of `scenario_text`.
    pub scenario_hash: u64,
    /// Set when this recording branches off another one.
    pub parent: Option<Parent>,
    /// Creation time, seconds since the Unix epoch.
    pub created_unix_s: u64,
}

/// Where a branched recording took over from its parent.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Parent {
    /// Parent recording's file name.
    pub file: String,
    /// [`Header::header_hash`] of the parent's header.
    pub hash_of_parent_header: u64,
    /// Simulation time taken over.
    pub t_s: f64,
    /// Simulation step taken over.
    pub step: u64,
}

/// FNV-1a 64-bit hash of a scenario file's text (the `scenario_hash` header field).
pub fn scenario_hash(text: &str) -> u64 {
    fnv1a64(text.as_bytes())
}

/// FNV-1a 64-bit hash.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

impl Header {
    /// A header for a fresh (non-branched) recording, stamped with the current time.
    pub fn new(
        program_version: impl Into<String>,
        backend: impl Into<String>,
        adapter: impl Into<String>,
        scenario_name: impl Into<String>,
        scenario_text: impl Into<String>,
    ) -> Self {
        let scenario_text = scenario_text.into();
        let created_unix_s =
            std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
        Header {
            format_version: FORMAT_VERSION,
            program_version: program_version.into(),
            backend: backend.into(),
            adapter: adapter.into(),
            scenario_name: scenario_name.into(),
            scenario_hash: scenario_hash(&scenario_text),
            scenario_text,
            parent: None,
            created_unix_s,
        }
    }

    /// Marks this recording as a branch of another one.
    pub fn with_parent(mut self, parent: Parent) -> Self {
        self.parent = Some(parent);
        self
    }

    /// FNV-1a 64 of the header's canonical encoding (its TLV fields as this module writes them): the value
    /// a branch stores in [`Parent::hash_of_parent_header`].
    pub fn header_hash(&self) -> u64 {
        fnv1a64(&encode_header_fields(self))
    }
}

fn put_field(out: &mut Vec<u8>, tag: u16, value: &[u8]) {
    out.extend_from_slice(&tag.to_le_bytes());
    out.extend_from_slice(&(value.len() as u32).to_le_bytes());
    out.extend_from_slice(value);
}

fn encode_header_fields(h: &Header) -> Vec<u8> {
    let mut out = Vec::with_capacity(128 + h.scenario_text.len());
    put_field(&mut out, TAG_PROGRAM_VERSION, h.program_version.as_bytes());
    put_field(&mut out, TAG_BACKEND, h.backend.as_bytes());
    put_field(&mut out, TAG_ADAPTER, h.adapter.as_bytes());
    put_field(&mut out, TAG_SCENARIO_NAME, h.scenario_name.as_bytes());
    put_field(&mut out, TAG_SCENARIO_TEXT, h.scenario_text.as_bytes());
    put_field(&mut out, TAG_SCENARIO_HASH, &h.scenario_hash.to_le_bytes());
    put_field(&mut out, TAG_CREATED, &h.created_unix_s.to_le_bytes());
    if let Some(p) = &h.parent {
        let mut v = Vec::with_capacity(24 + p.file.len());
        v.extend_from_slice(&p.hash_of_parent_header.to_le_bytes());
        v.extend_from_slice(&p.t_s.to_bits().to_le_bytes());
        v.extend_from_slice(&p.step.to_le_bytes());
        v.extend_from_slice(p.file.as_bytes());
        put_field(&mut out, TAG_PARENT, &v);
    }
    out
}

/// Encodes the complete file prefix: magic, version, header length, header fields, header CRC.
fn encode_prefix(h: &Header) -> Result<Vec<u8>, String> {
    if h.format_version != FORMAT_VERSION {
        return Err(format!(
            "header.format_version is {} but this writer writes version {FORMAT_VERSION} (use Header::new)",
            h.format_version
        ));
    }
    let expected = scenario_hash(&h.scenario_text);
    if h.scenario_hash != expected {
        return Err(format!(
            "header.scenario_hash is {:#018x} but scenario_text hashes to {expected:#018x} (use scenario_hash())",
            h.scenario_hash
        ));
    }
    let fields = encode_header_fields(h);
    let n = u32::try_from(fields.len()).ok().filter(|&n| n <= MAX_HEADER_LEN).ok_or_else(|| {
        format!("the header is {} bytes (mostly scenario text), above the {MAX_HEADER_LEN}-byte limit", fields.len())
    })?;
    let mut out = Vec::with_capacity(PREFIX_LEN + fields.len() + 4);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&n.to_le_bytes());
    out.extend_from_slice(&fields);
    let crc = crc32fast::hash(out.get(8..).unwrap_or(&[]));
    out.extend_from_slice(&crc.to_le_bytes());
    Ok(out)
}

/// Bounds-checked little-endian reader over a byte slice; every read returns `None` past the end.
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Cursor { bytes, pos: 0 }
    }
    fn is_empty(&self) -> bool {
        self.pos >= self.bytes.len()
    }
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let end = self.pos.checked_add(n)?;
        let s = self.bytes.get(self.pos..end)?;
        self.pos = end;
        Some(s)
    }
    fn rest(&mut self) -> &'a [u8] {
        let s = self.bytes.get(self.pos..).unwrap_or(&[]);
        self.pos = self.bytes.len();
        s
    }
    fn array<const N: usize>(&mut self) -> Option<[u8; N]> {
        self.take(N).and_then(|s| s.try_into().ok())
    }
    fn u8(&mut self) -> Option<u8> {
        self.array::<1>().map(|[b]| b)
    }
    fn u16(&mut self) -> Option<u16> {
        self.array().map(u16::from_le_bytes)
    }
    fn u32(&mut self) -> Option<u32> {
        self.array().map(u32::from_le_bytes)
    }
    fn u64(&mut self) -> Option<u64> {
        self.array().map(u64::from_le_bytes)
    }
    fn f64(&mut self) -> Option<f64> {
        self.u64().map(f64::from_bits)
    }
}

fn field_str(tag: u16, v: &[u8]) -> Result<String, String> {
    String::from_utf8(v.to_vec()).map_err(|e| format!("header field {} is not valid UTF-8 ({e})", tag_name(tag)))
}

fn field_u64(tag: u16, v: &[u8]) -> Result<u64, String> {
    <[u8; 8]>::try_from(v)
        .map(u64::from_le_bytes)
        .map_err(|_| format!("header field {} has {} bytes instead of 8", tag_name(tag), v.len()))
}

fn tag_name(tag: u16) -> String {
    let name = match tag {
        TAG_PROGRAM_VERSION => "program_version",
        TAG_BACKEND => "backend",
        TAG_ADAPTER => "adapter",
        TAG_SCENARIO_NAME => "scenario_name",
        TAG_SCENARIO_TEXT => "scenario_text",
        TAG_SCENARIO_HASH => "scenario_hash",
        TAG_CREATED => "created_unix_s",
        TAG_PARENT => "parent",
        _ => return format!("tag {tag}"),
    };
    format!("'{name}' (tag {tag})")
}

/// Why header fields could not be decoded.
enum HeaderFieldError {
    Corrupt(String),
    Unsupported(String),
}

fn decode_header_fields(fields: &[u8], format_version: u32) -> Result<Header, HeaderFieldError> {
    use HeaderFieldError::{Corrupt, Unsupported};
    let mut c = Cursor::new(fields);
    let mut strings: [Option<String>; 5] = Default::default();
    let mut hash = None;
    let mut created = None;
    let mut parent = None;
    let mut seen: Vec<u16> = Vec::new();
    while !c.is_empty() {
        let at = c.pos;
        let (Some(tag), Some(len)) = (c.u16(), c.u32()) else {
            return Err(Corrupt(format!("header field at byte {at} of the header is cut short")));
        };
        let Some(v) = c.take(len as usize) else {
            return Err(Corrupt(format!(
                "header field {} declares {len} bytes but only {} remain in the header",
                tag_name(tag),
                fields.len().saturating_sub(c.pos)
            )));
        };
        if seen.contains(&tag) {
            return Err(Corrupt(format!("header field {} appears twice", tag_name(tag))));
        }
        seen.push(tag);
        match tag {
            TAG_PROGRAM_VERSION..=TAG_SCENARIO_TEXT => {
                if let Some(slot) = strings.get_mut(usize::from(tag - TAG_PROGRAM_VERSION)) {
                    *slot = Some(field_str(tag, v).map_err(Corrupt)?);
                }
            }
            TAG_SCENARIO_HASH => hash = Some(field_u64(tag, v).map_err(Corrupt)?),
            TAG_CREATED => created = Some(field_u64(tag, v).map_err(Corrupt)?),
            TAG_PARENT => {
                let mut p = Cursor::new(v);
                let (Some(h), Some(t_s), Some(step)) = (p.u64(), p.f64(), p.u64()) else {
                    return Err(Corrupt(format!(
                        "header field 'parent' has only {} bytes (at least 24 needed)",
                        v.len()
                    )));
                };
                let file = field_str(tag, p.rest()).map_err(Corrupt)?;
                parent = Some(Parent { file, hash_of_parent_header: h, t_s, step });
            }
            t if t >= TAG_MUST_UNDERSTAND => {
                return Err(Unsupported(format!("the header has must-understand field tag {t:#06x}")));
            }
            _ => {} // optional field added by a later writer: skip
        }
    }
    let missing = |tag: u16| Corrupt(format!("required header field {} is missing", tag_name(tag)));
    let [pv, be, ad, sn, st] = strings;
    let header = Header {
        format_version,
        program_version: pv.ok_or_else(|| missing(TAG_PROGRAM_VERSION))?,
        backend: be.ok_or_else(|| missing(TAG_BACKEND))?,
        adapter: ad.ok_or_else(|| missing(TAG_ADAPTER))?,
        scenario_name: sn.ok_or_else(|| missing(TAG_SCENARIO_NAME))?,
        scenario_text: st.ok_or_else(|| missing(TAG_SCENARIO_TEXT))?,
        scenario_hash: hash.ok_or_else(|| missing(TAG_SCENARIO_HASH))?,
        parent,
        created_unix_s: created.ok_or_else(|| missing(TAG_CREATED))?,
    };
    let actual = scenario_hash(&header.scenario_text);
    if actual != header.scenario_hash {
        return Err(Corrupt(format!(
            "the stored scenario hash {:#018x} does not match the embedded scenario text (hash {actual:#018x})",
            header.scenario_hash
        )));
    }
    Ok(header)
}

// ------------------------------------------------------------------------------------------------------------
// Chunks, errors, warnings
// ------------------------------------------------------------------------------------------------------------

/// What a chunk's payload holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ChunkKind {
    /// A batch of timestamped viewer commands.
    Commands,
    /// Full simulation state for seeking.
    Keyframe,
    /// A state hash for divergence checks.
    StateHash,
    /// Free text.
    Note,
    /// End of recording (written by [`RecordingWriter::finish`]).
    End,
}

impl ChunkKind {
    /// All kinds, in byte-value order.
    pub const ALL: [ChunkKind; 5] =
        [ChunkKind::Commands, ChunkKind::Keyframe, ChunkKind::StateHash, ChunkKind::Note, ChunkKind::End];

    /// The kind byte on disk.
    pub const fn to_u8(self) -> u8 {
        match self {
            ChunkKind::Commands => 1,
            ChunkKind::Keyframe => 2,
            ChunkKind::StateHash => 3,
            ChunkKind::Note => 4,
            ChunkKind::End => 5,
        }
    }

    /// The kind for a byte on disk, `None` if unknown to this version.
    pub const fn from_u8(b: u8) -> Option<Self> {
        match b {
            1 => Some(ChunkKind::Commands),
            2 => Some(ChunkKind::Keyframe),
            3 => Some(ChunkKind::StateHash),
            4 => Some(ChunkKind::Note),
            5 => Some(ChunkKind::End),
            _ => None,
        }
    }

    /// Whether an unknown kind byte may be skipped (0x01..=0x7F) rather than stopping the replay.
    pub const fn is_skippable_unknown(b: u8) -> bool {
        b != 0 && b < 0x80
    }

    /// Human-readable name.
    pub const fn name(self) -> &'static str {
        match self {
            ChunkKind::Commands => "Commands",
            ChunkKind::Keyframe => "Keyframe",
            ChunkKind::StateHash => "StateHash",
            ChunkKind::Note => "Note",
            ChunkKind::End => "End",
        }
    }

    fn count_slot(self) -> Option<usize> {
        match self {
            ChunkKind::Commands => Some(0),
            ChunkKind::Keyframe => Some(1),
            ChunkKind::StateHash => Some(2),
            ChunkKind::Note => Some(3),
            ChunkKind::End => None,
        }
    }
}

impl fmt::Display for ChunkKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One decoded chunk (payload decompressed).
#[derive(Clone, Debug, PartialEq)]
pub struct Chunk {
    pub kind: ChunkKind,
    /// Simulation time, seconds.
    pub t_s: f64,
    /// Simulation step.
    pub step: u64,
    pub payload: Vec<u8>,
}

/// A recording cannot be read (or written) at all.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    #[error("'{file}' is not a Perfuse recording: {detail}. Open a .pfrec file written by Perfuse's recorder.")]
    NotARecording { file: String, detail: String },
    #[error(
        "'{file}' uses replay format version {found}, but this Perfuse build reads versions 1 to {supported}: \
         replay it with a newer Perfuse (if no newer Perfuse wrote it, the file is corrupted)"
    )]
    UnsupportedVersion { file: String, found: u32, supported: u32 },
    #[error(
        "'{file}' has a damaged header: {detail}. Without its header (scenario, backend) nothing can be \
         replayed: use an intact copy of the recording or record again"
    )]
    CorruptHeader { file: String, detail: String },
    #[error("'{file}' needs a feature this Perfuse build does not support ({detail}): replay it with a newer Perfuse")]
    UnsupportedFeature { file: String, detail: String },
    #[error("I/O error on recording '{file}': {source}. Check the path, permissions and free disk space")]
    Io {
        file: String,
        #[source]
        source: io::Error,
    },
    #[error(
        "recording '{file}' was made with scenario hash {expected:#018x}, but the scenario given hashes to \
         {found:#018x}: the scenario file changed since the recording was made. Replay with the scenario text \
         embedded in the recording (header.scenario_text) or record again"
    )]
    ScenarioMismatch { file: String, expected: u64, found: u64 },
    #[error("cannot start recording '{file}': invalid header: {detail}")]
    InvalidHeader { file: String, detail: String },
    #[error("cannot write chunk to recording '{file}': {detail}")]
    InvalidChunk { file: String, detail: String },
    #[error(
        "recording '{file}' can no longer be written because an earlier write failed; the file ends at its last \
         complete chunk and replays up to there. Start a new recording"
    )]
    WriterFailed { file: String },
}

/// Which checksum of a chunk failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChecksumPart {
    /// The 28-byte chunk header (kind, flags, time, step, lengths).
    ChunkHeader,
    /// The trailing CRC over header and payload (the header itself was intact, so the payload is damaged,
    /// or was spliced in from another chunk).
    Payload,
}

/// Something wrong with a readable recording. All variants but `UnknownChunkKind { skipped: true, .. }`,
/// `EndMismatch` and `TrailingData` mean the replay stops there ([`ReplayWarning::stops_replay`]).
/// `offset` is a byte offset in the file, `chunk_index` counts chunks from 0 (the header is not a chunk),
/// `chunks_kept`/`last_good_t_s` describe what survived (`last_good_t_s` is 0 when nothing did).
#[derive(Clone, Debug, PartialEq)]
pub enum ReplayWarning {
    /// The file ends inside a chunk.
    Truncated { offset: u64, chunk_index: u64, last_good_t_s: f64, chunks_kept: usize, detail: String },
    /// A chunk failed a CRC32 check.
    BadChecksum {
        offset: u64,
        chunk_index: u64,
        part: ChecksumPart,
        stored: u32,
        computed: u32,
        last_good_t_s: f64,
        chunks_kept: usize,
    },
    /// A chunk kind this build does not know: skipped if optional, otherwise the replay stops.
    UnknownChunkKind { offset: u64, chunk_index: u64, kind: u8, skipped: bool, last_good_t_s: f64, chunks_kept: usize },
    /// A chunk uses flag bits this build does not know (e.g. a newer compression).
    UnsupportedFlags { offset: u64, chunk_index: u64, flags: u8, last_good_t_s: f64, chunks_kept: usize },
    /// A chunk declares a length above the reader's limit.
    ChunkTooLarge { offset: u64, chunk_index: u64, len: u64, limit: u64, last_good_t_s: f64, chunks_kept: usize },
    /// A chunk passed its checksums but its payload is unusable (bad DEFLATE stream, length mismatch).
    BadPayload {
        offset: u64,
        chunk_index: u64,
        kind: ChunkKind,
        detail: String,
        last_good_t_s: f64,
        chunks_kept: usize,
    },
    /// An intact chunk with the wrong sequence number: chunks were removed, duplicated or reordered.
    OutOfSequence { offset: u64, chunk_index: u64, expected: u16, found: u16, last_good_t_s: f64, chunks_kept: usize },
    /// A chunk's time/step is not finite or goes backwards.
    OutOfOrder { offset: u64, chunk_index: u64, detail: String, last_good_t_s: f64, chunks_kept: usize },
    /// Decoded payloads would exceed [`ReadLimits::max_total_payload`].
    LimitReached { offset: u64, chunk_index: u64, limit: u64, last_good_t_s: f64, chunks_kept: usize },
    /// The file ends cleanly between chunks but has no End chunk (recording interrupted).
    MissingEnd { offset: u64, last_good_t_s: f64, chunks_kept: usize },
    /// The End chunk's counts disagree with the chunks read (chunks removed or duplicated).
    EndMismatch { detail: String },
    /// Bytes after the End chunk (ignored).
    TrailingData { offset: u64, len: u64 },
}

struct StopAt(f64, usize);

impl fmt::Display for StopAt {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.1 == 0 {
            write!(f, "the replay stops there; no chunk before it survived, only the header is usable")
        } else {
            write!(f, "the replay stops there, after {} good chunks (last good time t = {:.6} s)", self.1, self.0)
        }
    }
}

impl ReplayWarning {
    /// Whether this warning ended the chunk stream (everything after it was dropped).
    pub fn stops_replay(&self) -> bool {
        match self {
            ReplayWarning::UnknownChunkKind { skipped, .. } => !skipped,
            ReplayWarning::EndMismatch { .. } | ReplayWarning::TrailingData { .. } => false,
            _ => true,
        }
    }
}

impl fmt::Display for ReplayWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReplayWarning::Truncated { offset, chunk_index, last_good_t_s, chunks_kept, detail } => write!(
                f,
                "recording is truncated at byte {offset}, inside chunk #{chunk_index} ({detail}); {}. The writer \
                 was probably interrupted (crash, kill, full disk) and the rest is lost",
                StopAt(*last_good_t_s, *chunks_kept)
            ),
            ReplayWarning::BadChecksum { offset, chunk_index, part, stored, computed, last_good_t_s, chunks_kept } => {
                let what = match part {
                    ChecksumPart::ChunkHeader => "header (kind, time, step, lengths)",
                    ChecksumPart::Payload => "payload",
                };
                write!(
                    f,
                    "chunk #{chunk_index} at byte {offset} is corrupted: its {what} CRC32 is {computed:#010x} but \
                     {stored:#010x} was stored; {}. Use an intact copy to replay further",
                    StopAt(*last_good_t_s, *chunks_kept)
                )
            }
            ReplayWarning::UnknownChunkKind { offset, chunk_index, kind, skipped: true, .. } => write!(
                f,
                "chunk #{chunk_index} at byte {offset} has kind {kind:#04x}, unknown to this Perfuse build; it is \
                 optional and was skipped (a newer Perfuse may use it)"
            ),
            ReplayWarning::UnknownChunkKind {
                offset,
                chunk_index,
                kind,
                skipped: false,
                last_good_t_s,
                chunks_kept,
            } => {
                write!(
                    f,
                    "chunk #{chunk_index} at byte {offset} has kind {kind:#04x}, which this Perfuse build does not \
                     understand and must not skip; {}. Replay it with a newer Perfuse",
                    StopAt(*last_good_t_s, *chunks_kept)
                )
            }
            ReplayWarning::UnsupportedFlags { offset, chunk_index, flags, last_good_t_s, chunks_kept } => write!(
                f,
                "chunk #{chunk_index} at byte {offset} has flags {flags:#04x} with bits this Perfuse build does not \
                 understand (e.g. a newer compression); {}. Replay it with a newer Perfuse",
                StopAt(*last_good_t_s, *chunks_kept)
            ),
            ReplayWarning::ChunkTooLarge { offset, chunk_index, len, limit, last_good_t_s, chunks_kept } => write!(
                f,
                "chunk #{chunk_index} at byte {offset} declares a payload of {len} bytes, above the {limit}-byte \
                 limit: the file is corrupted (or needs larger ReadLimits); {}",
                StopAt(*last_good_t_s, *chunks_kept)
            ),
            ReplayWarning::BadPayload { offset, chunk_index, kind, detail, last_good_t_s, chunks_kept } => write!(
                f,
                "{kind} chunk #{chunk_index} at byte {offset} passed its checksums but its payload is unusable \
                 ({detail}); {}",
                StopAt(*last_good_t_s, *chunks_kept)
            ),
            ReplayWarning::OutOfSequence { offset, chunk_index, expected, found, last_good_t_s, chunks_kept } => {
                write!(
                    f,
                    "chunk #{chunk_index} at byte {offset} is intact but carries sequence number {found} instead of \
                 {expected}: chunks were removed, duplicated or reordered (e.g. by splicing or concatenating \
                 files); {}",
                    StopAt(*last_good_t_s, *chunks_kept)
                )
            }
            ReplayWarning::OutOfOrder { offset, chunk_index, detail, last_good_t_s, chunks_kept } => write!(
                f,
                "chunk #{chunk_index} at byte {offset} is out of order ({detail}): a replay must run forwards; {}",
                StopAt(*last_good_t_s, *chunks_kept)
            ),
            ReplayWarning::LimitReached { offset, chunk_index, limit, last_good_t_s, chunks_kept } => write!(
                f,
                "reading stopped at chunk #{chunk_index} at byte {offset}: decoded payloads would exceed the \
                 {limit}-byte memory limit; {}. Raise ReadLimits::max_total_payload or stream with ChunkReader",
                StopAt(*last_good_t_s, *chunks_kept)
            ),
            ReplayWarning::MissingEnd { offset, last_good_t_s, chunks_kept } => write!(
                f,
                "recording has no End chunk: it stops cleanly at byte {offset} after {chunks_kept} chunks (last \
                 time t = {last_good_t_s:.6} s). The writer was interrupted before finishing; everything up to \
                 there replays"
            ),
            ReplayWarning::EndMismatch { detail } => write!(
                f,
                "the End chunk's counts disagree with the chunks read ({detail}): chunks were probably removed or \
                 duplicated by an edit, so the replay may not be faithful"
            ),
            ReplayWarning::TrailingData { offset, len } => write!(
                f,
                "{len} bytes of unexpected data after the End chunk (from byte {offset}) were ignored; the file was \
                 probably appended to or padded"
            ),
        }
    }
}

// ------------------------------------------------------------------------------------------------------------
// Writer
// ------------------------------------------------------------------------------------------------------------

/// Writer settings.
#[derive(Clone, Debug)]
pub struct WriterOptions {
    /// DEFLATE level (0..=9) for keyframes, `None` to never compress. Other kinds are never compressed.
    pub compression_level: Option<u32>,
    /// Keyframes shorter than this are stored as is.
    pub compress_min_len: usize,
    /// Capacity of the internal `BufWriter`.
    pub buffer_capacity: usize,
    /// Name used in error messages (the file name).
    pub name: String,
}

impl Default for WriterOptions {
    fn default() -> Self {
        WriterOptions {
            compression_level: Some(DEFAULT_COMPRESSION_LEVEL),
            compress_min_len: DEFAULT_COMPRESS_MIN_LEN,
            buffer_capacity: 1 << 20,
            name: "<recording>".to_string(),
        }
    }
}

/// A chunk encoded (CRC computed, maybe compressed) ahead of writing, e.g. on a worker thread so the
/// simulation thread only appends bytes: see [`encode_chunk`] and [`RecordingWriter::write_encoded`].
#[derive(Clone, Debug)]
pub struct EncodedChunk {
    kind: ChunkKind,
    t_s: f64,
    step: u64,
    flags: u8,
    raw_len: usize,
    stored: Vec<u8>,
    /// CRC32 of `stored` alone; the writer folds in the header (which needs the sequence number).
    payload_crc: u32,
}

impl EncodedChunk {
    pub fn kind(&self) -> ChunkKind {
        self.kind
    }
    pub fn is_compressed(&self) -> bool {
        self.flags & FLAG_DEFLATE != 0
    }
    /// Payload bytes before compression.
    pub fn raw_len(&self) -> usize {
        self.raw_len
    }
    /// Payload bytes on disk.
    pub fn stored_len(&self) -> usize {
        self.stored.len()
    }
}

/// DEFLATE-compresses `payload` into `out` (cleared first); true if that saves at least 1/16 of the size.
fn deflate_pays(payload: &[u8], level: u32, out: &mut Vec<u8>) -> bool {
    let mut buf = std::mem::take(out);
    buf.clear();
    buf.reserve(payload.len() / 2);
    let mut enc = DeflateEncoder::new(buf, Compression::new(level.min(9)));
    if enc.write_all(payload).is_err() {
        return false;
    }
    match enc.finish() {
        Ok(buf) => {
            *out = buf;
            out.len() <= payload.len() - payload.len() / 16
        }
        Err(_) => false,
    }
}

fn wants_compression(kind: ChunkKind, len: usize, level: Option<u32>, min_len: usize) -> Option<u32> {
    level.filter(|_| kind == ChunkKind::Keyframe && len >= min_len && len > 0)
}

/// Encodes a chunk for [`RecordingWriter::write_encoded`]: CRC and (for keyframes of at least
/// `compress_min_len` bytes, when `compression_level` is set and it pays) DEFLATE compression. Thread-safe and
/// independent of any writer. Validation (kind, time order, size) happens when it is written.
pub fn encode_chunk(
    kind: ChunkKind,
    t_s: f64,
    step: u64,
    payload: &[u8],
    compression_level: Option<u32>,
    compress_min_len: usize,
) -> EncodedChunk {
    let mut stored = Vec::new();
    let mut flags = 0;
    if let Some(level) = wants_compression(kind, payload.len(), compression_level, compress_min_len)
        && deflate_pays(payload, level, &mut stored)
    {
        flags = FLAG_DEFLATE;
    } else {
        stored.clear();
        stored.extend_from_slice(payload);
    }
    let payload_crc = crc32fast::hash(&stored);
    EncodedChunk { kind, t_s, step, flags, raw_len: payload.len(), stored, payload_crc }
}

/// The trailing chunk CRC: CRC32 of the chunk header fields (bytes 0..28, *not* head_crc) followed by the
/// stored payload. Including head_crc would make the header's contribution constant (CRC residue property:
/// CRC(d ‖ CRC(d)) is the same for every d of a given length), so payloads could be swapped between chunks.
fn frame_crc(head: &[u8], stored: &[u8], payload_crc: Option<u32>) -> u32 {
    let mut h = crc32fast::Hasher::new();
    h.update(head.get(..CHUNK_HEADER_LEN - 4).unwrap_or(head));
    match payload_crc {
        // CRC of the concatenation from the two parts' CRCs (O(log n), no second pass over the payload)
        Some(crc) => h.combine(&crc32fast::Hasher::new_with_initial_len(crc, stored.len() as u64)),
        None => h.update(stored),
    }
    h.finalize()
}

/// Appends the 32-byte chunk header (with its CRC) to `out`.
#[allow(clippy::too_many_arguments)]
fn put_chunk_head(
    out: &mut Vec<u8>,
    kind: u8,
    flags: u8,
    seq: u16,
    t_s: f64,
    step: u64,
    stored_len: u32,
    raw_len: u32,
) {
    let start = out.len();
    out.push(kind);
    out.push(flags);
    out.extend_from_slice(&seq.to_le_bytes());
    out.extend_from_slice(&t_s.to_bits().to_le_bytes());
    out.extend_from_slice(&step.to_le_bytes());
    out.extend_from_slice(&stored_len.to_le_bytes());
    out.extend_from_slice(&raw_len.to_le_bytes());
    let crc = crc32fast::hash(out.get(start..).unwrap_or(&[]));
    out.extend_from_slice(&crc.to_le_bytes());
}

/// Streams a recording: header at creation, then chunks in time order, then [`finish`](Self::finish).
///
/// Output goes through an internal `BufWriter`; commands are written uncompressed, keyframes compressed
/// (fast level by default) when it pays. If the process dies without `finish`, the file still replays up to
/// its last complete chunk (call [`flush`](Self::flush) periodically to bound what a crash loses).
pub struct RecordingWriter<W: Write> {
    out: BufWriter<W>,
    opts: WriterOptions,
    bytes_written: u64,
    counts: [u64; 4],
    chunks: u64,
    last: Option<(f64, u64)>,
    scratch: Vec<u8>,
    head: Vec<u8>,
    failed: bool,
    /// Keyframes still to store raw without trying, after one did not compress well.
    compress_backoff: u32,
    compress_attempts: u64,
}

impl RecordingWriter<File> {
    /// Creates (truncates) `path` and writes the header.
    pub fn create(path: &Path, header: &Header) -> Result<Self, ReplayError> {
        let name = path.display().to_string();
        let file = File::create(path).map_err(|source| ReplayError::Io { file: name.clone(), source })?;
        RecordingWriter::with_options(file, header, WriterOptions { name, ..WriterOptions::default() })
    }
}

impl<W: Write> RecordingWriter<W> {
    /// Starts a recording on `w` with default options and writes the header.
    pub fn new(w: W, header: &Header) -> Result<Self, ReplayError> {
        Self::with_options(w, header, WriterOptions::default())
    }

    /// Starts a recording on `w` and writes the header.
    pub fn with_options(w: W, header: &Header, opts: WriterOptions) -> Result<Self, ReplayError> {
        let prefix =
            encode_prefix(header).map_err(|detail| ReplayError::InvalidHeader { file: opts.name.clone(), detail })?;
        let mut writer = RecordingWriter {
            out: BufWriter::with_capacity(opts.buffer_capacity.max(8192), w),
            opts,
            bytes_written: 0,
            counts: [0; 4],
            chunks: 0,
            last: None,
            scratch: Vec::new(),
            head: Vec::with_capacity(CHUNK_HEADER_LEN),
            failed: false,
            compress_backoff: 0,
            compress_attempts: 0,
        };
        writer.put(&prefix)?;
        Ok(writer)
    }

    fn io_err(&self, source: io::Error) -> ReplayError {
        ReplayError::Io { file: self.opts.name.clone(), source }
    }

    fn put(&mut self, bytes: &[u8]) -> Result<(), ReplayError> {
        if let Err(e) = self.out.write_all(bytes) {
            self.failed = true;
            return Err(self.io_err(e));
        }
        self.bytes_written += bytes.len() as u64;
        Ok(())
    }

    fn check(&self, kind: ChunkKind, t_s: f64, step: u64, len: usize) -> Result<(), ReplayError> {
        let invalid = |detail: String| Err(ReplayError::InvalidChunk { file: self.opts.name.clone(), detail });
        if self.failed {
            return Err(ReplayError::WriterFailed { file: self.opts.name.clone() });
        }
        if kind == ChunkKind::End {
            return invalid("End chunks are written by finish(), not write_chunk()".to_string());
        }
        if !t_s.is_finite() {
            return invalid(format!("the time stamp {t_s} is not finite"));
        }
        if let Some((lt, ls)) = self.last
            && (t_s < lt || step < ls)
        {
            return invalid(format!(
                "{kind} chunk at t = {t_s} s, step {step} goes back before the previous chunk (t = {lt} s, step \
                 {ls}); chunks must be written in time order (start a branch recording to go back)"
            ));
        }
        if len > MAX_CHUNK_LEN as usize {
            return invalid(format!("the {kind} payload is {len} bytes, above the {MAX_CHUNK_LEN}-byte chunk limit"));
        }
        Ok(())
    }

    /// Writes one frame. `kind` is a raw byte so tests can write kinds this version does not know.
    #[allow(clippy::too_many_arguments)]
    fn write_frame(
        &mut self,
        kind: u8,
        flags: u8,
        t_s: f64,
        step: u64,
        stored: &[u8],
        raw_len: usize,
        payload_crc: Option<u32>,
    ) -> Result<(), ReplayError> {
        let (Ok(stored_len), Ok(raw_len32)) = (u32::try_from(stored.len()), u32::try_from(raw_len)) else {
            return Err(ReplayError::InvalidChunk {
                file: self.opts.name.clone(),
                detail: format!("payload of {raw_len} bytes does not fit a chunk"),
            });
        };
        let mut head = std::mem::take(&mut self.head);
        head.clear();
        let seq = (self.chunks & 0xFFFF) as u16;
        put_chunk_head(&mut head, kind, flags, seq, t_s, step, stored_len, raw_len32);
        let crc = frame_crc(&head, stored, payload_crc);
        let result = self.put(&head).and_then(|()| self.put(stored)).and_then(|()| self.put(&crc.to_le_bytes()));
        self.head = head;
        result?;
        if let Some(slot) =
            ChunkKind::from_u8(kind).and_then(ChunkKind::count_slot).and_then(|i| self.counts.get_mut(i))
        {
            *slot += 1;
        }
        if kind != ChunkKind::End.to_u8() {
            self.chunks += 1;
        }
        self.last = Some((t_s, step));
        Ok(())
    }

    /// Appends a chunk. `t_s`/`step` must be finite and non-decreasing; keyframes are DEFLATE-compressed
    /// (per [`WriterOptions`]) when that saves at least 1/16; after one that does not, the next 8 keyframes
    /// are stored without trying. Errors: [`ReplayError::InvalidChunk`] (nothing
    /// written), [`ReplayError::Io`] (the writer is then failed: later calls return `WriterFailed`).
    pub fn write_chunk(&mut self, kind: ChunkKind, t_s: f64, step: u64, payload: &[u8]) -> Result<(), ReplayError> {
        self.check(kind, t_s, step, payload.len())?;
        let mut level = wants_compression(kind, payload.len(), self.opts.compression_level, self.opts.compress_min_len);
        if level.is_some() && self.compress_backoff > 0 {
            self.compress_backoff -= 1;
            level = None;
        }
        let mut scratch = std::mem::take(&mut self.scratch);
        let compressed = level.is_some_and(|level| {
            self.compress_attempts += 1;
            let pays = deflate_pays(payload, level, &mut scratch);
            if !pays {
                self.compress_backoff = COMPRESS_BACKOFF;
            }
            pays
        });
        let result = if compressed {
            self.write_frame(kind.to_u8(), FLAG_DEFLATE, t_s, step, &scratch, payload.len(), None)
        } else {
            self.write_frame(kind.to_u8(), 0, t_s, step, payload, payload.len(), None)
        };
        self.scratch = scratch;
        result
    }

    /// Appends a chunk prepared by [`encode_chunk`] (same rules as [`write_chunk`](Self::write_chunk)).
    pub fn write_encoded(&mut self, chunk: &EncodedChunk) -> Result<(), ReplayError> {
        self.check(chunk.kind, chunk.t_s, chunk.step, chunk.raw_len)?;
        self.write_frame(
            chunk.kind.to_u8(),
            chunk.flags,
            chunk.t_s,
            chunk.step,
            &chunk.stored,
            chunk.raw_len,
            Some(chunk.payload_crc),
        )
    }

    /// Flushes buffered bytes to the underlying writer (bounds what a crash loses).
    pub fn flush(&mut self) -> Result<(), ReplayError> {
        if let Err(e) = self.out.flush() {
            self.failed = true;
            return Err(self.io_err(e));
        }
        Ok(())
    }

    /// Bytes handed to the output so far (header included; some may still sit in the buffer).
    pub fn bytes_written(&self) -> u64 {
        self.bytes_written
    }

    /// Chunks written so far (End excluded).
    pub fn chunks_written(&self) -> u64 {
        self.chunks
    }

    /// The underlying writer.
    pub fn get_ref(&self) -> &W {
        self.out.get_ref()
    }

    /// Writes the End chunk, flushes, and returns the underlying writer.
    pub fn finish(mut self) -> Result<W, ReplayError> {
        if self.failed {
            return Err(ReplayError::WriterFailed { file: self.opts.name.clone() });
        }
        let mut p = Vec::with_capacity(END_PAYLOAD_LEN);
        p.extend_from_slice(&self.chunks.to_le_bytes());
        for c in self.counts {
            p.extend_from_slice(&c.to_le_bytes());
        }
        p.extend_from_slice(&self.bytes_written.to_le_bytes());
        let (t_s, step) = self.last.unwrap_or((0.0, 0));
        self.write_frame(ChunkKind::End.to_u8(), 0, t_s, step, &p, p.len(), None)?;
        self.flush()?;
        let name = self.opts.name;
        self.out.into_inner().map_err(|e| ReplayError::Io { file: name, source: e.into_error() })
    }
}

// ------------------------------------------------------------------------------------------------------------
// Reader
// ------------------------------------------------------------------------------------------------------------

/// Reader limits against corrupted or hostile files.
#[derive(Clone, Debug)]
pub struct ReadLimits {
    /// Largest header accepted.
    pub max_header_len: u32,
    /// Largest chunk payload accepted, stored or decompressed.
    pub max_chunk_len: u64,
    /// Largest sum of decoded payloads [`read_recording`] keeps in memory.
    pub max_total_payload: u64,
}

impl Default for ReadLimits {
    fn default() -> Self {
        ReadLimits {
            max_header_len: MAX_HEADER_LEN,
            max_chunk_len: u64::from(MAX_CHUNK_LEN),
            max_total_payload: 32 << 30,
        }
    }
}

/// Reads and checks the file prefix and header; returns the header and the offset of the first chunk.
pub fn read_header(bytes: &[u8], source: &str, limits: &ReadLimits) -> Result<(Header, usize), ReplayError> {
    let file = || source.to_string();
    let corrupt = |detail: String| ReplayError::CorruptHeader { file: file(), detail };
    let mut c = Cursor::new(bytes);
    let Some(magic) = c.take(MAGIC.len()) else {
        if bytes.is_empty() {
            return Err(ReplayError::NotARecording {
                file: file(),
                detail: "the file is empty (0 bytes); the recorder probably never wrote to it".to_string(),
            });
        }
        if MAGIC.starts_with(bytes) {
            return Err(corrupt(format!(
                "the file is only {} bytes long and ends inside the magic number; it was cut off right after it \
                 was created",
                bytes.len()
            )));
        }
        return Err(ReplayError::NotARecording {
            file: file(),
            detail: format!("it is only {} bytes long and does not start with the PERFUSE magic", bytes.len()),
        });
    };
    if magic != MAGIC {
        let shown: String = magic.iter().map(|b| format!("{b:02x} ")).collect();
        return Err(ReplayError::NotARecording {
            file: file(),
            detail: format!("it starts with bytes {}instead of the magic 'PERFUSE\\0'", shown),
        });
    }
    let Some(version) = c.u32() else {
        return Err(corrupt(format!("the file is only {} bytes long and ends inside the format version", bytes.len())));
    };
    if version == 0 {
        return Err(corrupt("the format version is 0, which no Perfuse writes".to_string()));
    }
    if version > FORMAT_VERSION {
        return Err(ReplayError::UnsupportedVersion { file: file(), found: version, supported: FORMAT_VERSION });
    }
    let Some(header_len) = c.u32() else {
        return Err(corrupt(format!("the file is only {} bytes long and ends inside the header length", bytes.len())));
    };
    if header_len > limits.max_header_len {
        return Err(corrupt(format!(
            "the header length field says {header_len} bytes, more than the {}-byte limit; the length field is \
             corrupted",
            limits.max_header_len
        )));
    }
    let (Some(fields), Some(stored_crc)) = (c.take(header_len as usize), c.u32()) else {
        return Err(corrupt(format!(
            "the header declares {header_len} bytes of fields plus a 4-byte checksum, but the file has only {} \
             bytes after its 16-byte prefix: it was cut inside the header or the length field is corrupted",
            bytes.len().saturating_sub(PREFIX_LEN)
        )));
    };
    let end = c.pos;
    let computed = crc32fast::hash(bytes.get(8..end.saturating_sub(4)).unwrap_or(&[]));
    if computed != stored_crc {
        return Err(corrupt(format!(
            "header checksum mismatch (CRC32 {computed:#010x}, stored {stored_crc:#010x}): bytes 8..{end} are \
             damaged"
        )));
    }
    match decode_header_fields(fields, version) {
        Ok(h) => Ok((h, end)),
        Err(HeaderFieldError::Corrupt(detail)) => Err(corrupt(detail)),
        Err(HeaderFieldError::Unsupported(detail)) => Err(ReplayError::UnsupportedFeature { file: file(), detail }),
    }
}

fn inflate(stored: &[u8], raw_len: usize) -> Result<Vec<u8>, String> {
    let max = (stored.len() as u64).saturating_mul(MAX_DEFLATE_RATIO).saturating_add(64);
    if raw_len as u64 > max {
        return Err(format!(
            "it claims {raw_len} bytes decompressed from {} stored bytes, beyond what DEFLATE can produce",
            stored.len()
        ));
    }
    // Preallocate only what the stored size makes plausible: a hostile raw_len must not reserve memory
    // that the stream never fills (`take` bounds the real growth).
    let mut out = Vec::with_capacity(raw_len.min(stored.len().saturating_mul(8).max(1 << 16)));
    let mut dec = DeflateDecoder::new(stored).take(raw_len as u64 + 1);
    dec.read_to_end(&mut out).map_err(|e| format!("cannot decompress the DEFLATE stream: {e}"))?;
    if out.len() != raw_len {
        let got = if out.len() > raw_len { "more than".to_string() } else { out.len().to_string() };
        return Err(format!("the DEFLATE stream decompressed to {got} bytes instead of the declared {raw_len}"));
    }
    Ok(out)
}

fn decode_payload(stored: &[u8], flags: u8, raw_len: usize) -> Result<Vec<u8>, String> {
    if flags & FLAG_DEFLATE != 0 {
        return inflate(stored, raw_len);
    }
    if stored.len() != raw_len {
        return Err(format!("stored uncompressed with {} bytes but raw_len says {raw_len}", stored.len()));
    }
    Ok(stored.to_vec())
}

struct RawHead {
    kind: u8,
    flags: u8,
    seq: u16,
    t_s: f64,
    step: u64,
    stored_len: u32,
    raw_len: u32,
    stored_crc: u32,
    computed_crc: u32,
}

fn parse_chunk_head(rest: &[u8]) -> Option<RawHead> {
    let head = rest.get(..CHUNK_HEADER_LEN)?;
    let mut c = Cursor::new(head);
    let kind = c.u8()?;
    let flags = c.u8()?;
    let seq = c.u16()?;
    Some(RawHead {
        kind,
        flags,
        seq,
        t_s: c.f64()?,
        step: c.u64()?,
        stored_len: c.u32()?,
        raw_len: c.u32()?,
        stored_crc: c.u32()?,
        computed_crc: crc32fast::hash(head.get(..CHUNK_HEADER_LEN - 4)?),
    })
}

/// Streaming chunk reader over an in-memory recording: yields good chunks in order and stops at the first
/// damaged one, recording why in [`warnings`](Self::warnings). Use it instead of [`read_recording`] to avoid
/// holding every decoded payload at once.
pub struct ChunkReader<'a> {
    bytes: &'a [u8],
    header: Header,
    limits: ReadLimits,
    pos: usize,
    frame_index: u64,
    kept: usize,
    last_kept_t: f64,
    last: Option<(f64, u64)>,
    counts: [u64; 4],
    total_payload: u64,
    warnings: Vec<ReplayWarning>,
    done: bool,
    complete: bool,
}

impl<'a> ChunkReader<'a> {
    /// Checks the header (errors as [`read_recording`]) and positions at the first chunk.
    pub fn new(bytes: &'a [u8], source: &str, limits: ReadLimits) -> Result<Self, ReplayError> {
        let (header, pos) = read_header(bytes, source, &limits)?;
        Ok(ChunkReader {
            bytes,
            header,
            limits,
            pos,
            frame_index: 0,
            kept: 0,
            last_kept_t: 0.0,
            last: None,
            counts: [0; 4],
            total_payload: 0,
            warnings: Vec::new(),
            done: false,
            complete: false,
        })
    }

    pub fn header(&self) -> &Header {
        &self.header
    }
    /// Warnings so far.
    pub fn warnings(&self) -> &[ReplayWarning] {
        &self.warnings
    }
    /// Whether the End chunk was reached.
    pub fn is_complete(&self) -> bool {
        self.complete
    }
    /// Byte offset just past the last good chunk (where damage starts, if any).
    pub fn good_len(&self) -> u64 {
        self.pos as u64
    }

    fn stop(&mut self, w: ReplayWarning) -> Option<Chunk> {
        self.warnings.push(w);
        self.done = true;
        None
    }

    fn check_end(&mut self, payload: &[u8], offset: usize) {
        let mut c = Cursor::new(payload);
        let fields: Option<[u64; 6]> = (|| Some([c.u64()?, c.u64()?, c.u64()?, c.u64()?, c.u64()?, c.u64()?]))();
        let Some([chunks, commands, keyframes, state_hashes, notes, end_offset]) = fields else {
            self.warnings.push(ReplayWarning::EndMismatch {
                detail: format!("its payload has {} bytes instead of at least {END_PAYLOAD_LEN}", payload.len()),
            });
            return;
        };
        let [rc, rk, rs, rn] = self.counts;
        let mut diffs = Vec::new();
        for (name, written, read) in [
            ("chunks", chunks, self.frame_index),
            ("Commands", commands, rc),
            ("Keyframes", keyframes, rk),
            ("StateHashes", state_hashes, rs),
            ("Notes", notes, rn),
            ("End offset", end_offset, offset as u64),
        ] {
            if written != read {
                diffs.push(format!("{name}: written {written}, read {read}"));
            }
        }
        if !diffs.is_empty() {
            self.warnings.push(ReplayWarning::EndMismatch { detail: diffs.join(", ") });
        }
    }

    /// The next good chunk, or `None` at the End chunk or at the first damage.
    pub fn next_chunk(&mut self) -> Option<Chunk> {
        loop {
            if self.done {
                return None;
            }
            let start = self.pos;
            let offset = start as u64;
            let chunk_index = self.frame_index;
            let (last_good_t_s, chunks_kept) = (self.last_kept_t, self.kept);
            let rest = self.bytes.get(start..).unwrap_or(&[]);
            if rest.is_empty() {
                return self.stop(ReplayWarning::MissingEnd { offset, last_good_t_s, chunks_kept });
            }
            let Some(h) = parse_chunk_head(rest) else {
                let detail = format!("{} of the {CHUNK_HEADER_LEN} chunk header bytes present", rest.len());
                return self.stop(ReplayWarning::Truncated { offset, chunk_index, last_good_t_s, chunks_kept, detail });
            };
            if h.stored_crc != h.computed_crc {
                return self.stop(ReplayWarning::BadChecksum {
                    offset,
                    chunk_index,
                    part: ChecksumPart::ChunkHeader,
                    stored: h.stored_crc,
                    computed: h.computed_crc,
                    last_good_t_s,
                    chunks_kept,
                });
            }
            if h.flags & !FLAG_DEFLATE != 0 {
                return self.stop(ReplayWarning::UnsupportedFlags {
                    offset,
                    chunk_index,
                    flags: h.flags,
                    last_good_t_s,
                    chunks_kept,
                });
            }
            let len = u64::from(h.stored_len.max(h.raw_len));
            if len > self.limits.max_chunk_len {
                let limit = self.limits.max_chunk_len;
                return self.stop(ReplayWarning::ChunkTooLarge {
                    offset,
                    chunk_index,
                    len,
                    limit,
                    last_good_t_s,
                    chunks_kept,
                });
            }
            let body = rest.get(CHUNK_HEADER_LEN..).unwrap_or(&[]);
            let stored_len = h.stored_len as usize;
            let (Some(stored), Some(crc_bytes)) =
                (body.get(..stored_len), stored_len.checked_add(CHUNK_CRC_LEN).and_then(|e| body.get(stored_len..e)))
            else {
                let kind =
                    ChunkKind::from_u8(h.kind).map_or_else(|| format!("kind {:#04x}", h.kind), |k| k.to_string());
                let detail = format!(
                    "{kind} chunk declaring {stored_len} payload bytes + {CHUNK_CRC_LEN} checksum bytes, only {} \
                     present",
                    body.len()
                );
                return self.stop(ReplayWarning::Truncated { offset, chunk_index, last_good_t_s, chunks_kept, detail });
            };
            let stored_crc = <[u8; 4]>::try_from(crc_bytes).map_or(0, u32::from_le_bytes);
            let computed = frame_crc(rest.get(..CHUNK_HEADER_LEN).unwrap_or(&[]), stored, None);
            if stored_crc != computed {
                return self.stop(ReplayWarning::BadChecksum {
                    offset,
                    chunk_index,
                    part: ChecksumPart::Payload,
                    stored: stored_crc,
                    computed,
                    last_good_t_s,
                    chunks_kept,
                });
            }
            let expected_seq = (chunk_index & 0xFFFF) as u16;
            if h.seq != expected_seq {
                return self.stop(ReplayWarning::OutOfSequence {
                    offset,
                    chunk_index,
                    expected: expected_seq,
                    found: h.seq,
                    last_good_t_s,
                    chunks_kept,
                });
            }
            let order_problem = if !h.t_s.is_finite() {
                Some(format!("its time stamp is {}", h.t_s))
            } else if let Some((lt, ls)) = self.last.filter(|&(lt, ls)| h.t_s < lt || h.step < ls) {
                Some(format!("t = {} s, step {} after t = {lt} s, step {ls}", h.t_s, h.step))
            } else {
                None
            };
            if let Some(detail) = order_problem {
                return self.stop(ReplayWarning::OutOfOrder {
                    offset,
                    chunk_index,
                    detail,
                    last_good_t_s,
                    chunks_kept,
                });
            }
            let frame_end = start + CHUNK_HEADER_LEN + stored_len + CHUNK_CRC_LEN;
            let Some(kind) = ChunkKind::from_u8(h.kind) else {
                let skipped = ChunkKind::is_skippable_unknown(h.kind);
                let w = ReplayWarning::UnknownChunkKind {
                    offset,
                    chunk_index,
                    kind: h.kind,
                    skipped,
                    last_good_t_s,
                    chunks_kept,
                };
                if !skipped {
                    return self.stop(w);
                }
                self.warnings.push(w);
                self.pos = frame_end;
                self.frame_index += 1;
                self.last = Some((h.t_s, h.step));
                continue;
            };
            let raw_len = h.raw_len as usize;
            if kind != ChunkKind::End
                && self.total_payload.saturating_add(raw_len as u64) > self.limits.max_total_payload
            {
                let limit = self.limits.max_total_payload;
                return self.stop(ReplayWarning::LimitReached {
                    offset,
                    chunk_index,
                    limit,
                    last_good_t_s,
                    chunks_kept,
                });
            }
            let payload = match decode_payload(stored, h.flags, raw_len) {
                Ok(p) => p,
                Err(detail) => {
                    return self.stop(ReplayWarning::BadPayload {
                        offset,
                        chunk_index,
                        kind,
                        detail,
                        last_good_t_s,
                        chunks_kept,
                    });
                }
            };
            self.pos = frame_end;
            self.last = Some((h.t_s, h.step));
            if kind == ChunkKind::End {
                self.check_end(&payload, start);
                self.complete = true;
                self.done = true;
                let trailing = self.bytes.len().saturating_sub(frame_end);
                if trailing > 0 {
                    self.warnings.push(ReplayWarning::TrailingData { offset: frame_end as u64, len: trailing as u64 });
                }
                return None;
            }
            if let Some(slot) = kind.count_slot().and_then(|i| self.counts.get_mut(i)) {
                *slot += 1;
            }
            self.frame_index += 1;
            self.kept += 1;
            self.last_kept_t = h.t_s;
            self.total_payload += raw_len as u64;
            return Some(Chunk { kind, t_s: h.t_s, step: h.step, payload });
        }
    }
}

impl Iterator for ChunkReader<'_> {
    type Item = Chunk;
    fn next(&mut self) -> Option<Chunk> {
        self.next_chunk()
    }
}

/// A fully read recording.
#[derive(Clone, Debug, PartialEq)]
pub struct Recording {
    pub header: Header,
    /// Good chunks in file order (End excluded), payloads decompressed.
    pub chunks: Vec<Chunk>,
    /// What was wrong; empty for a clean file.
    pub warnings: Vec<ReplayWarning>,
    /// The End chunk was reached.
    pub complete: bool,
    /// File name used in messages.
    pub source: String,
    /// Byte offset just past the last good chunk (a file cut there is a clean, End-less recording).
    pub good_len: u64,
}

/// Reads a whole recording from memory with default [`ReadLimits`]. Errors when the prefix or header is
/// unusable; otherwise returns every chunk up to the first damage, with warnings. `source` names the file in
/// messages. Never panics.
pub fn read_recording(bytes: &[u8], source: &str) -> Result<Recording, ReplayError> {
    read_recording_with_limits(bytes, source, ReadLimits::default())
}

/// [`read_recording`] with explicit limits.
pub fn read_recording_with_limits(bytes: &[u8], source: &str, limits: ReadLimits) -> Result<Recording, ReplayError> {
    let mut reader = ChunkReader::new(bytes, source, limits)?;
    let chunks: Vec<Chunk> = reader.by_ref().collect();
    Ok(Recording {
        header: reader.header,
        chunks,
        warnings: reader.warnings,
        complete: reader.complete,
        source: source.to_string(),
        good_len: reader.pos as u64,
    })
}

/// Reads a recording file (whole file in memory).
pub fn read_recording_file(path: &Path) -> Result<Recording, ReplayError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| ReplayError::Io { file: name.clone(), source })?;
    read_recording(&bytes, &name)
}

impl Recording {
    /// Index of the latest keyframe with `t_s <= t_s` (chunks are in time order).
    pub fn keyframe_index_at_or_before(&self, t_s: f64) -> Option<usize> {
        let end = self.chunks.partition_point(|c| c.t_s <= t_s);
        self.chunks.get(..end)?.iter().rposition(|c| c.kind == ChunkKind::Keyframe)
    }

    /// The latest keyframe at or before `t_s`: seek there, then re-apply the chunks after it.
    pub fn keyframe_at_or_before(&self, t_s: f64) -> Option<&Chunk> {
        self.keyframe_index_at_or_before(t_s).and_then(|i| self.chunks.get(i))
    }

    /// Errors with [`ReplayError::ScenarioMismatch`] unless `scenario_text` is the recorded scenario.
    pub fn check_scenario(&self, scenario_text: &str) -> Result<(), ReplayError> {
        let found = scenario_hash(scenario_text);
        if found == self.header.scenario_hash {
            Ok(())
        } else {
            Err(ReplayError::ScenarioMismatch { file: self.source.clone(), expected: self.header.scenario_hash, found })
        }
    }

    /// Chunks of one kind.
    pub fn chunks_of(&self, kind: ChunkKind) -> impl Iterator<Item = &Chunk> {
        self.chunks.iter().filter(move |c| c.kind == kind)
    }

    /// Time of the last good chunk (0 if none).
    pub fn last_t_s(&self) -> f64 {
        self.chunks.last().map_or(0.0, |c| c.t_s)
    }

    /// Complete and without warnings.
    pub fn is_clean(&self) -> bool {
        self.complete && self.warnings.is_empty()
    }

    /// Whether some chunks were lost (the stream stopped early).
    pub fn stopped_early(&self) -> bool {
        self.warnings.iter().any(ReplayWarning::stops_replay)
    }
}

#[cfg(test)]
#[allow(clippy::indexing_slicing, clippy::panic)]
mod tests {
    use super::*;

    // ---------------------------------------------------------------- helpers

    /// xorshift64 (Marsaglia), deterministic for fuzzing.
    struct Rng(u64);

    impl Rng {
        fn new(seed: u64) -> Self {
            Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1)
        }
        fn next(&mut self) -> u64 {
            let mut x = self.0;
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            self.0 = x;
            x
        }
        fn below(&mut self, n: usize) -> usize {
            if n == 0 { 0 } else { (self.next() % n as u64) as usize }
        }
        fn bytes(&mut self, n: usize) -> Vec<u8> {
            (0..n).map(|_| self.next() as u8).collect()
        }
    }

    const SCENARIO: &str = "Scenario(\n  name: \"liver_cut\",\n  particles: 100000,\n  dt_s: 1e-4,\n  \
                            tool: Scalpel(width_mm: 0.4),\n)\n// ünïcödé ✓ 肝臓\n";

    fn header() -> Header {
        Header {
            format_version: FORMAT_VERSION,
            program_version: "perfuse 0.1.0 (abc1234)".into(),
            backend: "wgpu/Vulkan".into(),
            adapter: "NVIDIA H100 80GB HBM3".into(),
            scenario_name: "liver_cut".into(),
            scenario_text: SCENARIO.into(),
            scenario_hash: scenario_hash(SCENARIO),
            parent: Some(Parent {
                file: "session-001.pfrec".into(),
                hash_of_parent_header: 0x1234_5678_9abc_def0,
                t_s: 1.234_567_890_123_456_7,
                step: 12_345,
            }),
            created_unix_s: 1_760_000_000,
        }
    }

    /// Particle-like keyframe payload: 64 B per particle (16 f32: lattice position + jitter, velocity,
    /// density, pressure, constants, phase, ...), compressible roughly like real SPH state.
    fn particles(n: usize, seed: u64) -> Vec<u8> {
        let mut rng = Rng::new(seed);
        let side = (n as f64).cbrt().ceil().max(1.0) as usize;
        let h = 0.002f32;
        let mut out = Vec::with_capacity(n * 64);
        for i in 0..n {
            let (x, y, z) = (i % side, (i / side) % side, i / (side * side));
            let mut noise = |scale: f32| (rng.next() % 10_000) as f32 / 10_000.0 * scale;
            let vals: [f32; 16] = [
                x as f32 * h + noise(1e-4),
                y as f32 * h + noise(1e-4),
                z as f32 * h + noise(1e-4),
                noise(0.01),
                noise(0.01),
                noise(0.01),
                1000.0 + noise(5.0),
                noise(200.0),
                8.0e-9,
                310.15,
                if i % 7 == 0 { 1.0 } else { 0.0 },
                0.3,
                0.25,
                (i % 12) as f32,
                0.0,
                0.0,
            ];
            for v in vals {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        out
    }

    /// A mix of every kind: keyframes every 9 chunks, paused stretches (same step), an empty payload.
    fn sample_chunks(n: usize, keyframe_particles: usize) -> Vec<Chunk> {
        let mut out = Vec::new();
        let mut step = 0u64;
        for i in 0..n {
            if i % 5 != 3 {
                step += 1 + (i as u64 % 3);
            }
            let t_s = step as f64 * 1e-4;
            let (kind, payload) = match i % 9 {
                0 => (ChunkKind::Keyframe, particles(keyframe_particles, i as u64)),
                4 => (ChunkKind::StateHash, fnv1a64(&(i as u64).to_le_bytes()).to_le_bytes().to_vec()),
                7 => (ChunkKind::Note, format!("note {i}: bleeding at vessel 3 ✓").into_bytes()),
                8 => (ChunkKind::Commands, Vec::new()),
                _ => (ChunkKind::Commands, (0..(i * 13) % 200).map(|b| (b * 31 + i) as u8).collect()),
            };
            out.push(Chunk { kind, t_s, step, payload });
        }
        out
    }

    fn small_opts() -> WriterOptions {
        WriterOptions { compress_min_len: 256, name: "test.pfrec".into(), ..WriterOptions::default() }
    }

    fn write_rec(h: &Header, chunks: &[Chunk], opts: WriterOptions) -> Vec<u8> {
        let mut w = RecordingWriter::with_options(Vec::new(), h, opts).unwrap();
        for c in chunks {
            w.write_chunk(c.kind, c.t_s, c.step, &c.payload).unwrap();
        }
        let n = w.bytes_written();
        let out = w.finish().unwrap();
        assert!(out.len() as u64 > n);
        out
    }

    /// Small recording used by the truncation, bit-flip and fuzz tests (~4 KB).
    fn small() -> (Vec<Chunk>, Vec<u8>) {
        let chunks = sample_chunks(SMALL_CHUNKS.into(), 24);
        let bytes = write_rec(&header(), &chunks, small_opts());
        let (_, fr) = frames(&bytes);
        assert!(fr.iter().any(|f| bytes[f.0 + 1] == FLAG_DEFLATE), "the small file must have compressed keyframes");
        (chunks, bytes)
    }

    /// Header end and (start, end, kind) of every chunk frame of a valid file (End included).
    fn frames(bytes: &[u8]) -> (usize, Vec<(usize, usize, u8)>) {
        let hl = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        let header_end = PREFIX_LEN + hl + 4;
        let mut pos = header_end;
        let mut v = Vec::new();
        while pos < bytes.len() {
            let s = u32::from_le_bytes(bytes[pos + 20..pos + 24].try_into().unwrap()) as usize;
            let end = pos + CHUNK_HEADER_LEN + s + CHUNK_CRC_LEN;
            v.push((pos, end, bytes[pos]));
            pos = end;
        }
        (header_end, v)
    }

    /// A chunk frame with valid CRCs and arbitrary field values.
    fn raw_frame_seq(seq: u16, kind: u8, flags: u8, t_s: f64, step: u64, stored: &[u8], raw_len: u32) -> Vec<u8> {
        let mut f = Vec::new();
        put_chunk_head(&mut f, kind, flags, seq, t_s, step, stored.len() as u32, raw_len);
        f.extend_from_slice(stored);
        let crc = frame_crc(&f[..CHUNK_HEADER_LEN], stored, None);
        f.extend_from_slice(&crc.to_le_bytes());
        f
    }

    /// Number of chunks in `small()`: the sequence number of a frame appended in place of its End chunk.
    const SMALL_CHUNKS: u16 = 20;

    /// A frame to append to `small()` in place of its End chunk.
    fn raw_frame(kind: u8, flags: u8, t_s: f64, step: u64, stored: &[u8], raw_len: u32) -> Vec<u8> {
        raw_frame_seq(SMALL_CHUNKS, kind, flags, t_s, step, stored, raw_len)
    }

    /// A file prefix with valid CRC around arbitrary header fields.
    fn prefix_from_fields(fields: &[u8]) -> Vec<u8> {
        let mut out = MAGIC.to_vec();
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&(fields.len() as u32).to_le_bytes());
        out.extend_from_slice(fields);
        let crc = crc32fast::hash(&out[8..]);
        out.extend_from_slice(&crc.to_le_bytes());
        out
    }

    fn deflate(data: &[u8]) -> Vec<u8> {
        let mut e = DeflateEncoder::new(Vec::new(), Compression::default());
        e.write_all(data).unwrap();
        e.finish().unwrap()
    }

    fn read(bytes: &[u8]) -> Recording {
        read_recording(bytes, "test.pfrec").unwrap()
    }

    fn err(bytes: &[u8]) -> ReplayError {
        match read_recording(bytes, "bad.pfrec") {
            Ok(r) => panic!("expected an error, got {} chunks and {:?}", r.chunks.len(), r.warnings),
            Err(e) => e,
        }
    }

    /// The one warning of a recording whose stream stopped early.
    fn only_warning(r: &Recording) -> &ReplayWarning {
        assert_eq!(r.warnings.len(), 1, "{:?}", r.warnings);
        &r.warnings[0]
    }

    // ---------------------------------------------------------------- round trips

    #[test]
    fn round_trip_all_kinds_with_compressed_keyframes() {
        let h = header();
        let chunks = sample_chunks(60, 500); // keyframes of 32 000 bytes
        let bytes = write_rec(&h, &chunks, WriterOptions::default());
        let r = read(&bytes);
        assert_eq!(r.header, h);
        assert_eq!(r.chunks, chunks);
        assert!(r.is_clean(), "{:?}", r.warnings);
        assert!(r.complete && !r.stopped_early());
        assert_eq!(r.good_len, bytes.len() as u64);
        for kind in [ChunkKind::Commands, ChunkKind::Keyframe, ChunkKind::StateHash, ChunkKind::Note] {
            assert!(r.chunks_of(kind).count() > 0, "{kind} missing");
        }
        // keyframes (and only keyframes) are stored compressed
        let (_, fr) = frames(&bytes);
        for &(start, _, kind) in &fr {
            assert_eq!(bytes[start + 1] == FLAG_DEFLATE, kind == ChunkKind::Keyframe.to_u8(), "kind {kind}");
        }
        let raw: usize = chunks.iter().map(|c| c.payload.len()).sum();
        assert!(bytes.len() < raw * 3 / 4, "file {} B for {raw} B of payloads", bytes.len());
        assert_eq!(r.last_t_s(), chunks.last().unwrap().t_s);
    }

    #[test]
    fn round_trip_without_parent_empty_strings_and_no_chunks() {
        let mut h = Header::new("", "", "", "", "");
        assert!(h.created_unix_s > 1_600_000_000);
        h.created_unix_s = 0;
        let bytes = write_rec(&h, &[], WriterOptions::default());
        let r = read(&bytes);
        assert_eq!(r.header, h);
        assert!(r.chunks.is_empty() && r.is_clean());
        assert_eq!(r.keyframe_at_or_before(1.0), None);
    }

    #[test]
    fn incompressible_or_disabled_keyframes_are_stored_raw() {
        let mut rng = Rng::new(7);
        let noise = rng.bytes(50_000);
        let good = particles(1000, 1);
        for (opts, payload, compressed) in [
            (WriterOptions::default(), &noise, false),
            (WriterOptions { compression_level: None, ..WriterOptions::default() }, &good, false),
            (WriterOptions { compress_min_len: 100_000, ..WriterOptions::default() }, &good, false),
            (WriterOptions { compression_level: Some(9), ..WriterOptions::default() }, &good, true),
            (WriterOptions { compression_level: Some(0), ..WriterOptions::default() }, &good, false),
        ] {
            let chunks = vec![Chunk { kind: ChunkKind::Keyframe, t_s: 0.5, step: 5, payload: payload.clone() }];
            let bytes = write_rec(&header(), &chunks, opts);
            let (_, fr) = frames(&bytes);
            assert_eq!(bytes[fr[0].0 + 1] == FLAG_DEFLATE, compressed);
            assert_eq!(read(&bytes).chunks, chunks);
        }
    }

    #[test]
    fn incompressible_keyframes_back_off() {
        let mut rng = Rng::new(11);
        let noise = rng.bytes(10_000);
        let good = particles(500, 2);
        let mut w = RecordingWriter::new(Vec::new(), &header()).unwrap();
        let mut chunks = Vec::new();
        for i in 0..12u64 {
            let payload = if i < 2 { noise.clone() } else { good.clone() };
            w.write_chunk(ChunkKind::Keyframe, i as f64, i, &payload).unwrap();
            chunks.push(Chunk { kind: ChunkKind::Keyframe, t_s: i as f64, step: i, payload });
        }
        // tried #0 (fails), skipped #1..=#8, tried #9 (pays), #10, #11
        assert_eq!(w.compress_attempts, 4);
        let bytes = w.finish().unwrap();
        let (_, fr) = frames(&bytes);
        let flags: Vec<u8> = fr[..12].iter().map(|f| bytes[f.0 + 1]).collect();
        assert_eq!(flags, [0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1]);
        assert_eq!(read(&bytes).chunks, chunks);
    }

    #[test]
    fn encode_chunk_on_a_worker_thread_then_write_encoded() {
        let payload = particles(2000, 3);
        let enc = std::thread::spawn(move || encode_chunk(ChunkKind::Keyframe, 0.25, 2500, &payload, Some(1), 4096))
            .join()
            .unwrap();
        assert!(enc.is_compressed() && enc.stored_len() < enc.raw_len());
        let mut w = RecordingWriter::new(Vec::new(), &header()).unwrap();
        w.write_chunk(ChunkKind::Commands, 0.1, 1000, b"cmd").unwrap();
        w.write_encoded(&enc).unwrap();
        let small = encode_chunk(ChunkKind::Commands, 0.3, 3000, b"x", Some(1), 0);
        assert!(!small.is_compressed());
        w.write_encoded(&small).unwrap();
        assert_eq!(w.chunks_written(), 3);
        let r = read(&w.finish().unwrap());
        assert!(r.is_clean());
        assert_eq!(r.chunks[1].payload, particles(2000, 3));
        assert_eq!(r.chunks[2].payload, b"x");
    }

    #[test]
    fn header_hash_and_serde() {
        let h = header();
        assert_eq!(h.header_hash(), header().header_hash());
        let mut h2 = header();
        h2.adapter.push('!');
        assert_ne!(h.header_hash(), h2.header_hash());
        let json = serde_json::to_string(&h).unwrap();
        assert_eq!(serde_json::from_str::<Header>(&json).unwrap().program_version, h.program_version);
        assert_eq!(scenario_hash(""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(scenario_hash("a"), 0xaf63_dc4c_8601_ec8c); // FNV-1a 64 reference value
    }

    #[test]
    fn file_round_trip_and_io_error_names_the_file() {
        let dir = std::env::temp_dir().join(format!("perfuse-replay-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("session.pfrec");
        let chunks = sample_chunks(12, 100);
        let mut w = RecordingWriter::create(&path, &header()).unwrap();
        for c in &chunks {
            w.write_chunk(c.kind, c.t_s, c.step, &c.payload).unwrap();
        }
        w.flush().unwrap();
        drop(w.finish().unwrap());
        let r = read_recording_file(&path).unwrap();
        assert!(r.is_clean());
        assert_eq!(r.chunks, chunks);
        assert!(r.source.ends_with("session.pfrec"));
        let missing = dir.join("missing.pfrec");
        let e = read_recording_file(&missing).unwrap_err();
        assert!(matches!(e, ReplayError::Io { .. }));
        assert!(e.to_string().contains("missing.pfrec"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn keyframe_at_or_before_seeks() {
        let chunks = sample_chunks(40, 10);
        let r = read(&write_rec(&header(), &chunks, small_opts()));
        let kfs: Vec<&Chunk> = chunks.iter().filter(|c| c.kind == ChunkKind::Keyframe).collect();
        assert!(kfs.len() >= 4);
        assert_eq!(r.keyframe_at_or_before(-1.0), None);
        assert_eq!(r.keyframe_at_or_before(f64::NAN), None);
        assert_eq!(r.keyframe_at_or_before(kfs[0].t_s).unwrap(), kfs[0]);
        assert_eq!(r.keyframe_at_or_before(kfs[2].t_s).unwrap(), kfs[2]);
        assert_eq!(r.keyframe_at_or_before(kfs[2].t_s - 1e-9).unwrap(), kfs[1]);
        assert_eq!(r.keyframe_at_or_before((kfs[2].t_s + kfs[3].t_s) / 2.0).unwrap(), kfs[2]);
        assert_eq!(r.keyframe_at_or_before(f64::INFINITY).unwrap(), *kfs.last().unwrap());
        let i = r.keyframe_index_at_or_before(kfs[1].t_s).unwrap();
        assert_eq!(&r.chunks[i], kfs[1]);
    }

    // ---------------------------------------------------------------- writer misuse and failures

    #[test]
    fn writer_rejects_invalid_headers_and_chunks() {
        let mut bad = header();
        bad.scenario_hash ^= 1;
        let e = RecordingWriter::new(Vec::new(), &bad).err().unwrap();
        assert!(matches!(e, ReplayError::InvalidHeader { .. }) && e.to_string().contains("scenario_hash"), "{e}");
        let mut bad = header();
        bad.format_version = 2;
        assert!(matches!(RecordingWriter::new(Vec::new(), &bad), Err(ReplayError::InvalidHeader { .. })));

        let mut w = RecordingWriter::new(Vec::new(), &header()).unwrap();
        w.write_chunk(ChunkKind::Commands, 1.0, 100, b"a").unwrap();
        let before = w.bytes_written();
        for (kind, t, step, what) in [
            (ChunkKind::End, 2.0, 200, "finish()"),
            (ChunkKind::Commands, f64::NAN, 200, "not finite"),
            (ChunkKind::Commands, f64::INFINITY, 200, "not finite"),
            (ChunkKind::Commands, 2.0, 99, "time order"),
            (ChunkKind::Keyframe, 0.5, 200, "time order"),
        ] {
            let e = w.write_chunk(kind, t, step, b"x").unwrap_err();
            assert!(matches!(e, ReplayError::InvalidChunk { .. }) && e.to_string().contains(what), "{e}");
        }
        assert_eq!(w.bytes_written(), before);
        w.write_chunk(ChunkKind::Commands, 1.0, 100, b"same time is fine (paused)").unwrap();
        let r = read(&w.finish().unwrap());
        assert!(r.is_clean() && r.chunks.len() == 2);
    }

    /// Accepts `budget` bytes, then fails like a full disk.
    struct FailingWriter {
        data: Vec<u8>,
        budget: usize,
    }

    impl Write for FailingWriter {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            if self.data.len() + buf.len() > self.budget {
                return Err(io::Error::other("disk full"));
            }
            self.data.extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn writer_io_failure_poisons_the_writer_and_the_file_replays_to_the_last_good_chunk() {
        let chunks = sample_chunks(20, 24);
        let mut w = RecordingWriter::with_options(
            FailingWriter { data: Vec::new(), budget: 3000 },
            &header(),
            WriterOptions { buffer_capacity: 0, name: "full.pfrec".into(), ..small_opts() },
        )
        .unwrap();
        let mut failed_at = None;
        for (i, c) in chunks.iter().enumerate() {
            // bytes are buffered, so the failure shows at write_chunk or at flush
            if let Err(e) = w.write_chunk(c.kind, c.t_s, c.step, &c.payload).and_then(|()| w.flush()) {
                assert!(matches!(e, ReplayError::Io { .. }) && e.to_string().contains("disk full"), "{e}");
                failed_at = Some(i);
                break;
            }
        }
        let failed_at = failed_at.expect("budget too large for the test");
        let e = w.write_chunk(ChunkKind::Note, 99.0, 999_999, b"later").unwrap_err();
        assert!(matches!(e, ReplayError::WriterFailed { .. }) && e.to_string().contains("full.pfrec"), "{e}");
        let data = w.get_ref().data.clone();
        assert!(matches!(w.finish(), Err(ReplayError::WriterFailed { .. })));
        let r = read(&data);
        assert_eq!(r.chunks, chunks[..failed_at]);
        assert!(!r.complete && r.stopped_early());
    }

    #[test]
    fn dropped_writer_gives_missing_end_with_all_chunks() {
        let chunks = sample_chunks(10, 24);
        let mut buf = Vec::new();
        {
            let mut w = RecordingWriter::with_options(&mut buf, &header(), small_opts()).unwrap();
            for c in &chunks {
                w.write_chunk(c.kind, c.t_s, c.step, &c.payload).unwrap();
            }
        } // dropped without finish(): simulator crash after the buffer was flushed
        let r = read(&buf);
        assert_eq!(r.chunks, chunks);
        assert!(!r.complete);
        let w = only_warning(&r);
        assert!(matches!(w, ReplayWarning::MissingEnd { chunks_kept: 10, .. }), "{w:?}");
        assert!(w.to_string().contains("no End chunk"), "{w}");
    }

    // ---------------------------------------------------------------- truncation

    #[test]
    fn truncation_at_every_byte_offset() {
        let (chunks, bytes) = small();
        let (header_end, fr) = frames(&bytes);
        assert_eq!(fr.len(), chunks.len() + 1);
        let boundaries: Vec<usize> = std::iter::once(header_end).chain(fr.iter().map(|f| f.1)).collect();
        for cut in 0..=bytes.len() {
            let res = read_recording(&bytes[..cut], "cut.pfrec");
            if cut < header_end {
                let e = res.err().unwrap_or_else(|| panic!("cut {cut} inside the header must fail"));
                let msg = e.to_string();
                assert!(msg.contains("cut.pfrec"), "{msg}");
                match cut {
                    0 => assert!(matches!(e, ReplayError::NotARecording { .. }) && msg.contains("empty"), "{msg}"),
                    _ => assert!(matches!(e, ReplayError::CorruptHeader { .. }), "cut {cut}: {msg}"),
                }
                continue;
            }
            let r = res.unwrap_or_else(|e| panic!("cut {cut}: {e}"));
            let kept = fr.iter().filter(|f| f.1 <= cut && f.2 != ChunkKind::End.to_u8()).count();
            assert_eq!(r.chunks, chunks[..kept], "cut {cut}");
            if cut == bytes.len() {
                assert!(r.is_clean());
                continue;
            }
            assert!(!r.complete, "cut {cut}");
            let good = boundaries.iter().copied().filter(|&b| b <= cut).max().unwrap();
            assert_eq!(r.good_len, good as u64);
            let w = only_warning(&r);
            if boundaries.contains(&cut) {
                assert!(matches!(w, ReplayWarning::MissingEnd { chunks_kept, .. } if *chunks_kept == kept), "{w:?}");
            } else {
                match w {
                    ReplayWarning::Truncated { offset, chunks_kept, last_good_t_s, .. } => {
                        assert_eq!((*offset, *chunks_kept), (good as u64, kept), "cut {cut}");
                        let t = if kept == 0 { 0.0 } else { chunks[kept - 1].t_s };
                        assert_eq!(*last_good_t_s, t);
                    }
                    _ => panic!("cut {cut}: {w:?}"),
                }
                assert!(w.to_string().contains("truncated"), "{w}");
            }
        }
    }

    // ---------------------------------------------------------------- named corrupted-file cases

    #[test]
    fn corrupt_01_empty_file() {
        let e = err(&[]);
        assert!(matches!(e, ReplayError::NotARecording { .. }), "{e:?}");
        let msg = e.to_string();
        assert!(msg.contains("bad.pfrec") && msg.contains("empty") && msg.contains("Perfuse"), "{msg}");
    }

    #[test]
    fn corrupt_02_random_bytes() {
        let mut rng = Rng::new(2);
        for len in [1, 7, 8, 100, 4096] {
            let e = err(&rng.bytes(len));
            assert!(matches!(e, ReplayError::NotARecording { .. }), "{e:?}");
            assert!(e.to_string().contains("PERFUSE"), "{e}");
        }
    }

    #[test]
    fn corrupt_03_wrong_magic() {
        let (_, mut bytes) = small();
        bytes[..8].copy_from_slice(b"\x89PNG\r\n\x1a\n");
        let e = err(&bytes);
        assert!(matches!(e, ReplayError::NotARecording { .. }), "{e:?}");
        assert!(e.to_string().contains("89 50 4e 47") && e.to_string().contains("magic"), "{e}");
        bytes[..8].copy_from_slice(b"perfuse\0"); // case matters
        assert!(matches!(err(&bytes), ReplayError::NotARecording { .. }));
    }

    #[test]
    fn corrupt_04_newer_version() {
        let (_, mut bytes) = small();
        bytes[8..12].copy_from_slice(&2u32.to_le_bytes());
        let e = err(&bytes);
        assert!(matches!(e, ReplayError::UnsupportedVersion { found: 2, supported: FORMAT_VERSION, .. }), "{e:?}");
        assert!(e.to_string().contains("version 2") && e.to_string().contains("newer Perfuse"), "{e}");
    }

    #[test]
    fn corrupt_05_version_zero() {
        let (_, mut bytes) = small();
        bytes[8..12].copy_from_slice(&0u32.to_le_bytes());
        let e = err(&bytes);
        assert!(matches!(e, ReplayError::CorruptHeader { .. }) && e.to_string().contains("version is 0"), "{e}");
    }

    #[test]
    fn corrupt_06_header_crc_flipped() {
        let (_, bytes) = small();
        let (header_end, _) = frames(&bytes);
        for pos in [20, header_end / 2, header_end - 5, header_end - 1] {
            let mut b = bytes.clone();
            b[pos] ^= 0x10;
            let e = err(&b);
            assert!(matches!(e, ReplayError::CorruptHeader { .. }), "{e:?}");
            assert!(e.to_string().contains("checksum mismatch") && e.to_string().contains("intact copy"), "{e}");
        }
    }

    #[test]
    fn corrupt_07_header_length_absurd() {
        let (_, bytes) = small();
        let mut b = bytes.clone();
        b[12..16].copy_from_slice(&0xFFFF_FFF0u32.to_le_bytes());
        let e = err(&b);
        assert!(matches!(e, ReplayError::CorruptHeader { .. }) && e.to_string().contains("limit"), "{e}");
        // plausible but beyond the end of the file
        let mut b = bytes.clone();
        b[12..16].copy_from_slice(&(bytes.len() as u32).to_le_bytes());
        let e = err(&b);
        assert!(matches!(e, ReplayError::CorruptHeader { .. }) && e.to_string().contains("cut inside"), "{e}");
    }

    #[test]
    fn corrupt_08_chunk_payload_crc_flipped() {
        let (chunks, bytes) = small();
        let (_, fr) = frames(&bytes);
        let (start, end, _) = fr[3];
        let mut b = bytes.clone();
        b[(start + CHUNK_HEADER_LEN + end - CHUNK_CRC_LEN) / 2] ^= 0x01;
        let r = read(&b);
        assert_eq!(r.chunks, chunks[..3]);
        assert!(!r.complete);
        let w = only_warning(&r);
        assert!(
            matches!(w, ReplayWarning::BadChecksum { part: ChecksumPart::Payload, chunk_index: 3, chunks_kept: 3, offset, .. } if *offset == start as u64),
            "{w:?}"
        );
        assert!(w.to_string().contains("corrupted") && w.to_string().contains("after 3 good chunks"), "{w}");
        // the stored CRC itself damaged
        let mut b = bytes.clone();
        b[end - 1] ^= 0x80;
        assert!(matches!(only_warning(&read(&b)), ReplayWarning::BadChecksum { part: ChecksumPart::Payload, .. }));
    }

    /// Fuzz regression (seed 13, iteration 11 479 015 of `fuzz_long`, first design): duplicating a byte range
    /// put StateHash #13's 8-byte payload and its CRC right after StateHash #4's header. With a CRC over the
    /// payload alone that read as a valid chunk #4 carrying #13's hash. A CRC over header (with head_crc) and
    /// payload still passed, because CRC(d ‖ CRC(d)) is constant; the trailing CRC now covers header bytes
    /// 0..28 and the payload.
    #[test]
    fn regression_payload_spliced_from_another_chunk() {
        let (chunks, bytes) = small();
        let (_, fr) = frames(&bytes);
        let hashes: Vec<_> = fr.iter().filter(|f| f.2 == ChunkKind::StateHash.to_u8()).collect();
        let (a, b) = (hashes[0], hashes[1]);
        assert_eq!(a.1 - a.0, b.1 - b.0, "same payload length");
        let k = fr.iter().position(|f| f == a).unwrap();
        // the residue property that defeated the second design
        assert_eq!(crc32fast::hash(&bytes[a.0..a.0 + 32]), crc32fast::hash(&bytes[b.0..b.0 + 32]));
        for replace in [false, true] {
            let mut damaged = bytes[..a.0 + CHUNK_HEADER_LEN].to_vec();
            damaged.extend_from_slice(&bytes[b.0 + CHUNK_HEADER_LEN..b.1]);
            damaged.extend_from_slice(&bytes[if replace { a.1 } else { a.0 + CHUNK_HEADER_LEN }..]);
            let r = read(&damaged);
            assert_eq!(r.chunks, chunks[..k]);
            let w = only_warning(&r);
            assert!(matches!(w, ReplayWarning::BadChecksum { part: ChecksumPart::Payload, .. }), "{w:?}");
        }
    }

    #[test]
    fn corrupt_09_chunk_header_field_flipped() {
        let (chunks, bytes) = small();
        let (_, fr) = frames(&bytes);
        for field_byte in [0, 1, 2, 5, 13, 21, 26, 29] {
            let mut b = bytes.clone();
            b[fr[5].0 + field_byte] ^= 0x04;
            let r = read(&b);
            assert_eq!(r.chunks, chunks[..5]);
            let w = only_warning(&r);
            assert!(matches!(w, ReplayWarning::BadChecksum { part: ChecksumPart::ChunkHeader, .. }), "{w:?}");
            assert!(w.to_string().contains("header (kind, time, step, lengths)"), "{w}");
        }
    }

    #[test]
    fn corrupt_10_chunk_length_absurd() {
        let (chunks, bytes) = small();
        let (_, fr) = frames(&bytes);
        let end_start = fr.last().unwrap().0;
        // a flipped length byte is caught by the chunk header CRC
        let mut b = bytes.clone();
        b[fr[2].0 + 23] ^= 0x40;
        let r = read(&b);
        assert_eq!(r.chunks, chunks[..2]);
        assert!(matches!(only_warning(&r), ReplayWarning::BadChecksum { part: ChecksumPart::ChunkHeader, .. }));
        // a self-consistent header declaring 4 GiB: refused by the limit, nothing allocated
        let mut b = bytes[..end_start].to_vec();
        put_chunk_head(&mut b, 1, 0, SMALL_CHUNKS, 100.0, 1 << 40, u32::MAX, u32::MAX);
        b.extend_from_slice(&[0u8; 64]);
        let r = read(&b);
        assert_eq!(r.chunks, chunks);
        let w = only_warning(&r);
        assert!(matches!(w, ReplayWarning::ChunkTooLarge { len: 0xFFFF_FFFF, .. }), "{w:?}");
        assert!(w.to_string().contains("above the 1073741824-byte limit"), "{w}");
        // below the limit but beyond the end of the file: truncation, not a huge allocation
        let mut b = bytes[..end_start].to_vec();
        put_chunk_head(&mut b, 1, 0, SMALL_CHUNKS, 100.0, 1 << 40, 1 << 29, 1 << 29);
        b.extend_from_slice(&[0u8; 64]);
        let w = only_warning(&read(&b)).clone();
        assert!(matches!(w, ReplayWarning::Truncated { .. }) && w.to_string().contains("declaring 536870912"), "{w}");
    }

    #[test]
    fn corrupt_11_unknown_chunk_kinds() {
        let chunks = sample_chunks(6, 24);
        // optional kind 0x42: skipped with a warning, the stream goes on and End counts still match
        let mut w = RecordingWriter::with_options(Vec::new(), &header(), small_opts()).unwrap();
        for (i, c) in chunks.iter().enumerate() {
            w.write_chunk(c.kind, c.t_s, c.step, &c.payload).unwrap();
            if i == 2 {
                w.write_frame(0x42, 0, c.t_s, c.step, b"future", 6, None).unwrap();
            }
        }
        let r = read(&w.finish().unwrap());
        assert_eq!(r.chunks, chunks);
        assert!(r.complete && !r.stopped_early());
        let warn = only_warning(&r);
        assert!(matches!(warn, ReplayWarning::UnknownChunkKind { kind: 0x42, skipped: true, chunk_index: 3, .. }));
        assert!(warn.to_string().contains("skipped"), "{warn}");
        // must-understand kinds (0x00, 0x80..) stop the replay
        for kind in [0x00, 0x80, 0xFE, 0xFF] {
            let mut w = RecordingWriter::with_options(Vec::new(), &header(), small_opts()).unwrap();
            for (i, c) in chunks.iter().enumerate() {
                w.write_chunk(c.kind, c.t_s, c.step, &c.payload).unwrap();
                if i == 2 {
                    w.write_frame(kind, 0, c.t_s, c.step, b"", 0, None).unwrap();
                }
            }
            let r = read(&w.finish().unwrap());
            assert_eq!(r.chunks, chunks[..3]);
            let warn = only_warning(&r);
            assert!(matches!(warn, ReplayWarning::UnknownChunkKind { skipped: false, .. }), "{warn:?}");
            assert!(warn.to_string().contains("newer Perfuse"), "{warn}");
        }
    }

    #[test]
    fn corrupt_12_truncated_mid_payload() {
        let (chunks, bytes) = small();
        let (_, fr) = frames(&bytes);
        let (start, end, kind) = fr[9];
        assert_eq!(kind, ChunkKind::Keyframe.to_u8());
        let r = read(&bytes[..(start + end) / 2]);
        assert_eq!(r.chunks, chunks[..9]);
        let w = only_warning(&r);
        assert!(matches!(w, ReplayWarning::Truncated { chunk_index: 9, chunks_kept: 9, .. }), "{w:?}");
        let msg = w.to_string();
        assert!(msg.contains("Keyframe chunk declaring") && msg.contains("interrupted"), "{msg}");
        assert!(msg.contains(&format!("t = {:.6} s", chunks[8].t_s)), "{msg}");
    }

    #[test]
    fn corrupt_13_truncated_mid_chunk_header() {
        let (chunks, bytes) = small();
        let (_, fr) = frames(&bytes);
        let r = read(&bytes[..fr[4].0 + 11]);
        assert_eq!(r.chunks, chunks[..4]);
        let w = only_warning(&r);
        assert!(matches!(w, ReplayWarning::Truncated { .. }), "{w:?}");
        assert!(w.to_string().contains("11 of the 32 chunk header bytes present"), "{w}");
    }

    fn with_frame_before_end(frame: &[u8]) -> (Vec<Chunk>, Recording) {
        let (chunks, bytes) = small();
        let (_, fr) = frames(&bytes);
        let mut b = bytes[..fr.last().unwrap().0].to_vec();
        b.extend_from_slice(frame);
        (chunks, read(&b))
    }

    #[test]
    fn corrupt_14_compressed_payload_corrupted() {
        // valid CRCs around a payload that is not a DEFLATE stream (0xFF: reserved block type)
        let (chunks, r) = with_frame_before_end(&raw_frame(2, FLAG_DEFLATE, 100.0, 1 << 40, &[0xFF; 40], 1000));
        assert_eq!(r.chunks, chunks);
        let w = only_warning(&r);
        assert!(matches!(w, ReplayWarning::BadPayload { kind: ChunkKind::Keyframe, .. }), "{w:?}");
        assert!(w.to_string().contains("cannot decompress"), "{w}");
        // a valid DEFLATE stream whose length disagrees with raw_len
        let stored = deflate(&[7u8; 100]);
        let (_, r) = with_frame_before_end(&raw_frame(2, FLAG_DEFLATE, 100.0, 1 << 40, &stored, 200));
        assert!(only_warning(&r).to_string().contains("decompressed to 100 bytes instead of the declared 200"));
        let (_, r) = with_frame_before_end(&raw_frame(2, FLAG_DEFLATE, 100.0, 1 << 40, &stored, 50));
        assert!(only_warning(&r).to_string().contains("more than bytes instead of the declared 50"));
        // an uncompressed chunk whose raw_len disagrees with its stored length
        let (_, r) = with_frame_before_end(&raw_frame(1, 0, 100.0, 1 << 40, b"abc", 4));
        assert!(matches!(only_warning(&r), ReplayWarning::BadPayload { .. }));
        // the writer's own compressed keyframe, truncated DEFLATE stream re-checksummed
        let (_, bytes) = small();
        let (_, fr) = frames(&bytes);
        let (s, e, _) = fr[0];
        let stored = &bytes[s + CHUNK_HEADER_LEN..e - CHUNK_CRC_LEN];
        let raw_len = u32::from_le_bytes(bytes[s + 24..s + 28].try_into().unwrap());
        let f = raw_frame_seq(0, 2, FLAG_DEFLATE, 0.0, 0, &stored[..stored.len() / 2], raw_len);
        let mut b = bytes[..s].to_vec();
        b.extend_from_slice(&f);
        let r = read(&b);
        assert!(r.chunks.is_empty() && matches!(only_warning(&r), ReplayWarning::BadPayload { .. }), "{r:?}");
    }

    #[test]
    fn corrupt_15_decompression_bomb_is_bounded() {
        // 1 KiB stored claiming 1 GiB: more than DEFLATE's maximum ratio, rejected before allocating
        let (_, r) = with_frame_before_end(&raw_frame(2, FLAG_DEFLATE, 100.0, 1 << 40, &[0u8; 1024], MAX_CHUNK_LEN));
        assert!(only_warning(&r).to_string().contains("beyond what DEFLATE can produce"), "{:?}", r.warnings);
        // a real bomb (8 MiB of zeros in ~8 KiB) under a 1 MiB reader limit
        let zeros = vec![0u8; 8 << 20];
        let stored = deflate(&zeros);
        assert!(stored.len() < 16 << 10);
        let (_, bytes) = small();
        let (_, fr) = frames(&bytes);
        let mut b = bytes[..fr.last().unwrap().0].to_vec();
        b.extend_from_slice(&raw_frame(2, FLAG_DEFLATE, 100.0, 1 << 40, &stored, zeros.len() as u32));
        let limits = ReadLimits { max_chunk_len: 1 << 20, ..ReadLimits::default() };
        let r = read_recording_with_limits(&b, "bomb.pfrec", limits).unwrap();
        assert!(matches!(only_warning(&r), ReplayWarning::ChunkTooLarge { len: 0x80_0000, limit: 0x10_0000, .. }));
        // and it does decode under the default limit (it is a valid chunk)
        assert_eq!(read(&b).chunks.last().unwrap().payload.len(), 8 << 20);
        // the total-memory limit stops a long file cleanly
        let limits = ReadLimits { max_total_payload: 5 << 20, ..ReadLimits::default() };
        let r = read_recording_with_limits(&b, "bomb.pfrec", limits).unwrap();
        let w = only_warning(&r);
        assert!(matches!(w, ReplayWarning::LimitReached { .. }) && w.to_string().contains("ChunkReader"), "{w}");
    }

    #[test]
    fn corrupt_16_scenario_hash_mismatch() {
        let r = read(&small().1);
        r.check_scenario(SCENARIO).unwrap();
        let edited = SCENARIO.replace("0.4", "0.5");
        let e = r.check_scenario(&edited).unwrap_err();
        assert!(matches!(e, ReplayError::ScenarioMismatch { expected, found, .. }
            if expected == scenario_hash(SCENARIO) && found == scenario_hash(&edited)));
        let msg = e.to_string();
        assert!(msg.contains("test.pfrec") && msg.contains("changed") && msg.contains("embedded"), "{msg}");
    }

    #[test]
    fn corrupt_17_trailing_garbage_after_end() {
        let (chunks, mut bytes) = small();
        let len = bytes.len();
        bytes.extend_from_slice(b"garbage that someone appended");
        let r = read(&bytes);
        assert_eq!(r.chunks, chunks);
        assert!(r.complete && !r.stopped_early());
        let w = only_warning(&r);
        assert_eq!(*w, ReplayWarning::TrailingData { offset: len as u64, len: 29 });
        assert!(w.to_string().contains("29 bytes"), "{w}");
        // a second recording concatenated after the first is trailing data too
        let (_, second) = small();
        let mut b = small().1;
        b.extend_from_slice(&second);
        assert!(matches!(only_warning(&read(&b)), ReplayWarning::TrailingData { .. }));
    }

    #[test]
    fn corrupt_18_unsupported_flags() {
        let (chunks, r) = with_frame_before_end(&raw_frame(2, 0x02, 100.0, 1 << 40, b"zstd?", 5));
        assert_eq!(r.chunks, chunks);
        let w = only_warning(&r);
        assert!(matches!(w, ReplayWarning::UnsupportedFlags { flags: 0x02, .. }), "{w:?}");
        assert!(w.to_string().contains("newer Perfuse"), "{w}");
    }

    #[test]
    fn corrupt_19_out_of_order_and_non_finite_time() {
        for (t, step, what) in [(0.0, 1 << 40, "after t ="), (1e9, 0, "step 0 after"), (f64::NAN, 1 << 40, "NaN")] {
            let (chunks, r) = with_frame_before_end(&raw_frame(1, 0, t, step, b"cmd", 3));
            assert_eq!(r.chunks, chunks);
            let w = only_warning(&r);
            assert!(matches!(w, ReplayWarning::OutOfOrder { .. }) && w.to_string().contains(what), "{w}");
        }
    }

    #[test]
    fn corrupt_20_duplicated_removed_or_swapped_chunk_stops_at_the_gap() {
        let (chunks, bytes) = small();
        let (_, fr) = frames(&bytes);
        let (s, e, _) = fr[6];
        let (s2, e2, _) = fr[7];
        // chunk 6 duplicated (an intact frame, same time and step: only its sequence number shows it)
        let mut dup = bytes[..e].to_vec();
        dup.extend_from_slice(&bytes[s..]);
        // chunk 6 removed
        let mut removed = bytes[..s].to_vec();
        removed.extend_from_slice(&bytes[e..]);
        // chunks 6 and 7 swapped
        let mut swapped = bytes[..s].to_vec();
        swapped.extend_from_slice(&bytes[s2..e2]);
        swapped.extend_from_slice(&bytes[s..e]);
        swapped.extend_from_slice(&bytes[e2..]);
        for (b, kept, expected, found) in [(dup, 7, 7, 6), (removed, 6, 6, 7), (swapped, 6, 6, 7)] {
            let r = read(&b);
            assert_eq!(r.chunks, chunks[..kept]);
            let w = only_warning(&r);
            assert!(
                matches!(w, ReplayWarning::OutOfSequence { expected: x, found: y, .. } if *x == expected && *y == found),
                "{w:?}"
            );
            assert!(w.to_string().contains("removed, duplicated or reordered"), "{w}");
        }
    }

    #[test]
    fn corrupt_20b_end_counts_disagree() {
        let chunks = sample_chunks(10, 24);
        let mut w = RecordingWriter::with_options(Vec::new(), &header(), small_opts()).unwrap();
        for c in &chunks {
            w.write_chunk(c.kind, c.t_s, c.step, &c.payload).unwrap();
        }
        w.counts[1] += 1; // a writer bug: one keyframe too many counted
        let r = read(&w.finish().unwrap());
        assert_eq!(r.chunks, chunks);
        assert!(r.complete && !r.stopped_early());
        let warn = only_warning(&r);
        assert!(matches!(warn, ReplayWarning::EndMismatch { .. }), "{warn:?}");
        assert!(warn.to_string().contains("Keyframes: written 3, read 2"), "{warn}");
    }

    #[test]
    fn corrupt_21_header_fields() {
        let good = encode_header_fields(&header());
        // optional unknown tag from a newer writer: skipped
        let mut f = good.clone();
        put_field(&mut f, 0x0100, b"future optional field");
        let (_, fr) = frames(&small().1);
        let body = &small().1[fr[0].0..];
        let mut b = prefix_from_fields(&f);
        b.extend_from_slice(body);
        let r = read(&b);
        assert_eq!(r.header, header());
        assert_eq!(r.chunks, small().0);
        assert!(r.complete && !r.stopped_early());
        // the header grew but the End chunk was not rewritten: its recorded offset disagrees
        assert!(only_warning(&r).to_string().contains("End offset"), "{:?}", r.warnings);
        let cases: Vec<(Vec<u8>, &str)> = vec![
            (
                {
                    let mut f = good.clone();
                    put_field(&mut f, 0x8001, b"x");
                    f
                },
                "must-understand",
            ),
            (
                {
                    let mut f = good.clone();
                    put_field(&mut f, TAG_BACKEND, b"twice");
                    f
                },
                "appears twice",
            ),
            (good[..good.len() - 3].to_vec(), "declares"),
            (encode_header_fields(&header())[..6 + header().program_version.len()].to_vec(), "missing"),
            (
                {
                    let mut h = header();
                    h.scenario_hash ^= 0xff;
                    encode_header_fields(&h)
                },
                "does not match the embedded scenario",
            ),
            (
                {
                    let mut f = Vec::new();
                    put_field(&mut f, TAG_PROGRAM_VERSION, &[0xC3, 0x28]);
                    f
                },
                "UTF-8",
            ),
            (
                {
                    let mut f = Vec::new();
                    put_field(&mut f, TAG_SCENARIO_HASH, &[1, 2, 3]);
                    f
                },
                "instead of 8",
            ),
            (
                {
                    let mut f = Vec::new();
                    put_field(&mut f, TAG_PARENT, &[0; 10]);
                    f
                },
                "at least 24",
            ),
            (vec![1, 0, 5], "cut short"),
        ];
        for (fields, what) in cases {
            let e = err(&prefix_from_fields(&fields));
            assert!(e.to_string().contains(what), "{what}: {e}");
            let expect_unsupported = what == "must-understand";
            assert_eq!(matches!(e, ReplayError::UnsupportedFeature { .. }), expect_unsupported, "{e:?}");
            assert_eq!(matches!(e, ReplayError::CorruptHeader { .. }), !expect_unsupported, "{e:?}");
        }
    }

    #[test]
    fn corrupt_22_short_files_and_truncated_prefix() {
        let (_, bytes) = small();
        for (len, what) in [(3, "magic"), (8, "format version"), (10, "format version"), (14, "header length")] {
            let e = err(&bytes[..len]);
            assert!(matches!(e, ReplayError::CorruptHeader { .. }) && e.to_string().contains(what), "{len}: {e}");
        }
        assert!(matches!(err(b"PERFUSX"), ReplayError::NotARecording { .. }));
    }

    #[test]
    fn warnings_have_clear_messages() {
        let stop = |w: &ReplayWarning| (w.stops_replay(), w.to_string());
        let all = [
            ReplayWarning::Truncated {
                offset: 9,
                chunk_index: 1,
                last_good_t_s: 0.5,
                chunks_kept: 1,
                detail: "d".into(),
            },
            ReplayWarning::BadChecksum {
                offset: 9,
                chunk_index: 0,
                part: ChecksumPart::Payload,
                stored: 1,
                computed: 2,
                last_good_t_s: 0.0,
                chunks_kept: 0,
            },
            ReplayWarning::UnknownChunkKind {
                offset: 9,
                chunk_index: 0,
                kind: 0x90,
                skipped: false,
                last_good_t_s: 0.0,
                chunks_kept: 0,
            },
            ReplayWarning::UnsupportedFlags { offset: 9, chunk_index: 0, flags: 4, last_good_t_s: 0.0, chunks_kept: 0 },
            ReplayWarning::ChunkTooLarge {
                offset: 9,
                chunk_index: 0,
                len: 5,
                limit: 4,
                last_good_t_s: 0.0,
                chunks_kept: 0,
            },
            ReplayWarning::BadPayload {
                offset: 9,
                chunk_index: 0,
                kind: ChunkKind::Note,
                detail: "d".into(),
                last_good_t_s: 0.0,
                chunks_kept: 0,
            },
            ReplayWarning::OutOfOrder {
                offset: 9,
                chunk_index: 0,
                detail: "d".into(),
                last_good_t_s: 0.0,
                chunks_kept: 0,
            },
            ReplayWarning::LimitReached { offset: 9, chunk_index: 0, limit: 1, last_good_t_s: 0.0, chunks_kept: 0 },
            ReplayWarning::OutOfSequence {
                offset: 9,
                chunk_index: 0,
                expected: 0,
                found: 1,
                last_good_t_s: 0.0,
                chunks_kept: 0,
            },
        ];
        for w in &all {
            let (stops, msg) = stop(w);
            assert!(stops && msg.contains("replay stops there") && msg.contains("byte 9"), "{msg}");
        }
        assert!(stop(&all[0]).1.contains("after 1 good chunks (last good time t = 0.500000 s)"));
        assert!(stop(&all[1]).1.contains("only the header is usable"));
        assert!(ReplayWarning::MissingEnd { offset: 1, last_good_t_s: 0.0, chunks_kept: 0 }.stops_replay());
        assert!(!ReplayWarning::EndMismatch { detail: "x".into() }.stops_replay());
        assert!(!ReplayWarning::TrailingData { offset: 1, len: 2 }.stops_replay());
    }

    // ---------------------------------------------------------------- exhaustive flips and fuzzing

    /// Every single-bit flip anywhere in a small file: the header ones are errors, the chunk ones keep exactly
    /// the chunks before the damaged one (CRC32 detects every single-bit error).
    #[test]
    fn every_single_bit_flip_is_detected() {
        let (chunks, bytes) = small();
        let (header_end, fr) = frames(&bytes);
        for pos in 0..bytes.len() {
            for bit in 0..8 {
                let mut b = bytes.clone();
                b[pos] ^= 1 << bit;
                let res = read_recording(&b, "flip.pfrec");
                if pos < header_end {
                    assert!(res.is_err(), "flip at {pos}.{bit} in the header must be an error");
                    continue;
                }
                let r = res.unwrap_or_else(|e| panic!("flip at {pos}.{bit}: {e}"));
                let frame = fr.iter().position(|f| f.0 <= pos && pos < f.1).unwrap();
                assert_eq!(r.chunks, chunks[..frame.min(chunks.len())], "flip at {pos}.{bit}");
                assert!(!r.complete, "flip at {pos}.{bit}");
                assert!(only_warning(&r).stops_replay());
            }
        }
    }

    /// 1 to 4 random edits: bit flip, byte set, insert, delete, truncate, "interesting" u32, duplicate a range.
    fn mutate(rng: &mut Rng, original: &[u8]) -> Vec<u8> {
        let mut b = original.to_vec();
        for _ in 0..1 + rng.below(4) {
            let pos = rng.below(b.len() + 1);
            match rng.below(8) {
                0 if pos < b.len() => b[pos] ^= 1 << rng.below(8),
                1 if pos < b.len() => b[pos] = rng.next() as u8,
                2 => {
                    let n = 1 + rng.below(8);
                    let ins = rng.bytes(n);
                    b.splice(pos..pos, ins);
                }
                3 => {
                    let end = (pos + 1 + rng.below(40)).min(b.len());
                    b.drain(pos..end);
                }
                4 => b.truncate(pos),
                5 if pos + 4 <= b.len() => {
                    let v: u32 = [0, 1, 0x7FFF_FFFF, 0xFFFF_FFFF, 0x8000_0000, b.len() as u32][rng.below(6)];
                    b[pos..pos + 4].copy_from_slice(&v.to_le_bytes());
                }
                6 => {
                    let src = rng.below(b.len() + 1);
                    let end = (src + 1 + rng.below(300)).min(b.len());
                    let copy = b[src..end].to_vec();
                    b.splice(pos..pos, copy);
                }
                _ => {
                    if pos < b.len() {
                        b[pos] = b[pos].wrapping_add(1);
                    }
                }
            }
        }
        b
    }

    /// Properties of reading a damaged copy of a recording of `chunks`: never panics; every chunk returned is
    /// one of the originals; a clean read is exact; warnings are displayable.
    fn check_damaged(b: &[u8], chunks: &[Chunk]) -> Result<(), String> {
        match read_recording(b, "fuzz.pfrec") {
            Err(e) if e.to_string().is_empty() => Err("empty error message".into()),
            Err(_) => Ok(()),
            Ok(r) => {
                if let Some(c) = r.chunks.iter().find(|c| !chunks.contains(c)) {
                    return Err(format!("a chunk not in the original survived: {c:?}"));
                }
                if r.is_clean() && r.chunks != chunks {
                    return Err("a clean read must be exact".into());
                }
                if r.complete && r.stopped_early() {
                    return Err("complete but stopped early".into());
                }
                if r.warnings.iter().any(|w| w.to_string().is_empty()) {
                    return Err("empty warning message".into());
                }
                let _ = r.keyframe_at_or_before(r.last_t_s());
                Ok(())
            }
        }
    }

    fn fuzz(seed: u64, iters: u64) {
        let (chunks, bytes) = small();
        let mut rng = Rng::new(seed);
        for i in 0..iters {
            let b = mutate(&mut rng, &bytes);
            if let Err(e) = check_damaged(&b, &chunks) {
                if let Ok(dir) = std::env::var("FUZZ_OUT") {
                    std::fs::write(format!("{dir}/fuzz-{seed}-{i}.pfrec"), &b).unwrap();
                }
                panic!("seed {seed}, iteration {i}: {e}");
            }
        }
    }

    #[test]
    fn fuzz_random_edits_never_panic() {
        fuzz(0x5EED_2026, 25_000);
    }

    /// Structure-aware fuzz past the CRCs: chunks whose checksums are valid but whose fields and payloads are
    /// random or damaged DEFLATE streams (what a buggy writer could produce). Exercises the length, order,
    /// flag and decompression checks that CRC-breaking edits never reach.
    #[test]
    fn fuzz_chunks_with_valid_checksums() {
        let (chunks, bytes) = small();
        let (_, fr) = frames(&bytes);
        let end_start = fr.last().unwrap().0;
        let kf = fr.iter().find(|f| bytes[f.0 + 1] == FLAG_DEFLATE).unwrap();
        let kf_stored = bytes[kf.0 + CHUNK_HEADER_LEN..kf.1 - CHUNK_CRC_LEN].to_vec();
        let kf_raw = u32::from_le_bytes(bytes[kf.0 + 24..kf.0 + 28].try_into().unwrap());
        let last_t = chunks.last().unwrap().t_s;
        let last_step = chunks.last().unwrap().step;
        let mut rng = Rng::new(0xC0FF_EE00);
        let limits = ReadLimits { max_chunk_len: 1 << 20, ..ReadLimits::default() };
        for i in 0..20_000 {
            let n = rng.below(64);
            let mut stored = if rng.below(2) == 0 { kf_stored.clone() } else { rng.bytes(n) };
            for _ in 0..rng.below(4) {
                if !stored.is_empty() {
                    let p = rng.below(stored.len());
                    let bit = rng.below(8);
                    stored[p] ^= 1 << bit;
                }
            }
            if rng.below(4) == 0 {
                stored.truncate(rng.below(stored.len() + 1));
            }
            let kind = [1, 2, 3, 4, 5, 0x42, 0x90, 0][rng.below(8)];
            let flags = [0, FLAG_DEFLATE, FLAG_DEFLATE, 0x02][rng.below(4)];
            let raw_len = match rng.below(4) {
                0 => kf_raw,
                1 => stored.len() as u32,
                2 => rng.next() as u32,
                _ => rng.below(1 << 21) as u32,
            };
            let t = [last_t, last_t + 1.0, last_t - 1.0, f64::NAN][rng.below(4)];
            let step = [last_step, last_step + 5, last_step.saturating_sub(1)][rng.below(3)];
            let mut b = bytes[..end_start].to_vec();
            let seq = if rng.below(8) == 0 { rng.next() as u16 } else { SMALL_CHUNKS };
            b.extend_from_slice(&raw_frame_seq(seq, kind, flags, t, step, &stored, raw_len));
            if rng.below(2) == 0 {
                b.extend_from_slice(&bytes[end_start..]);
            }
            let r = read_recording_with_limits(&b, "fuzz.pfrec", limits.clone())
                .unwrap_or_else(|e| panic!("case {i}: the header is intact, yet {e}"));
            assert_eq!(r.chunks[..chunks.len()], chunks[..], "case {i}");
            assert!(r.chunks.len() <= chunks.len() + 1, "case {i}");
            if let Some(extra) = r.chunks.get(chunks.len()) {
                assert_eq!(extra.payload.len(), raw_len as usize, "case {i}");
            }
            for w in &r.warnings {
                assert!(!w.to_string().is_empty());
            }
        }
    }

    /// Long fuzz run (a failing input is saved to $FUZZ_OUT if set):
    /// `FUZZ_ITERS=15000000 FUZZ_SEED=7 cargo test --release fuzz_long -- --ignored`.
    #[test]
    #[ignore]
    fn fuzz_long() {
        let iters: u64 = std::env::var("FUZZ_ITERS").ok().and_then(|s| s.parse().ok()).unwrap_or(1_000_000);
        let seed: u64 = std::env::var("FUZZ_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(1);
        fuzz(seed, iters);
    }
}
