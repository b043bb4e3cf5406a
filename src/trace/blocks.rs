//! Block framing of a version 3 recording. After the magic and the version, the file is a
//! sequence of blocks, each
//!
//! | field        | bytes | meaning                                        |
//! |--------------|-------|------------------------------------------------|
//! | `seq`        | 4     | 0, 1, 2, ... in file order                      |
//! | `kind`       | 1     | [`BlockKind`]                                   |
//! | `len`        | 4     | payload bytes, at most [`MAX_PAYLOAD_BYTES`]    |
//! | `header_crc` | 4     | CRC-32 of the 9 bytes before it                 |
//! | payload      | `len` |                                                 |
//! | `payload_crc`| 4     | CRC-32 of the payload                           |
//!
//! all little-endian. The header has its own checksum so that a corrupted `len` is told from a
//! file that simply stops (a session killed mid-write): the first is an error, the second keeps
//! every complete block before it.

use std::io;

pub(super) const MAGIC: &[u8; 8] = b"VSLTRACE";
/// The block-structured format; versions 1 and 2 (one monolithic record) still read.
pub(super) const VERSION: u32 = 3;
/// Magic and version.
pub(super) const PREAMBLE_BYTES: usize = MAGIC.len() + 4;
/// `seq`, `kind`, `len`, `header_crc`.
pub(super) const HEADER_BYTES: usize = 4 + 1 + 4 + 4;
/// The payload's checksum after it.
pub(super) const TRAILER_BYTES: usize = 4;
/// The largest payload a reader accepts: far above any block the writer makes (a second of
/// frames at the smallest step is under 1 MiB), so a larger `len` can only be corruption, and a
/// reader never trusts it to size a buffer.
pub(super) const MAX_PAYLOAD_BYTES: u32 = 64 << 20;

/// What a block holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum BlockKind {
    Header = 1,
    Frames = 2,
    Tuning = 3,
    End = 4,
}

impl BlockKind {
    pub(super) fn from_byte(b: u8) -> Option<Self> {
        match b {
            1 => Some(Self::Header),
            2 => Some(Self::Frames),
            3 => Some(Self::Tuning),
            4 => Some(Self::End),
            _ => None,
        }
    }

    pub(super) fn name(self) -> &'static str {
        match self {
            Self::Header => "header",
            Self::Frames => "frames",
            Self::Tuning => "tuning",
            Self::End => "end",
        }
    }
}

/// The magic and version that open a version 3 file.
pub(super) fn preamble() -> [u8; PREAMBLE_BYTES] {
    let mut p = [0; PREAMBLE_BYTES];
    p[..MAGIC.len()].copy_from_slice(MAGIC);
    p[MAGIC.len()..].copy_from_slice(&VERSION.to_le_bytes());
    p
}

/// Replaces `out` by one framed block whose payload is `parts` one after the other (so a caller
/// can frame a payload head and a large body without copying them together first).
pub(super) fn encode(
    seq: u32,
    kind: BlockKind,
    parts: &[&[u8]],
    out: &mut Vec<u8>,
) -> io::Result<()> {
    let len = parts.iter().map(|p| p.len()).sum::<usize>();
    let len = u32::try_from(len)
        .ok()
        .filter(|l| *l <= MAX_PAYLOAD_BYTES)
        .ok_or_else(|| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "a {} block of {len} bytes is over the {MAX_PAYLOAD_BYTES} byte limit",
                    kind.name()
                ),
            )
        })?;
    out.clear();
    out.extend_from_slice(&seq.to_le_bytes());
    out.push(kind as u8);
    out.extend_from_slice(&len.to_le_bytes());
    let header_crc = crc32fast::hash(out);
    out.extend_from_slice(&header_crc.to_le_bytes());
    let mut h = crc32fast::Hasher::new();
    for p in parts {
        h.update(p);
        out.extend_from_slice(p);
    }
    out.extend_from_slice(&h.finalize().to_le_bytes());
    Ok(())
}

/// One block whose header and payload checksums matched.
#[derive(Debug)]
pub(super) struct RawBlock<'a> {
    pub seq: u32,
    /// The kind byte as stored (an unknown kind is the caller's error to name).
    pub kind: u8,
    pub payload: &'a [u8],
}

impl RawBlock<'_> {
    /// Bytes the block takes in the file, header and trailer included.
    pub(super) fn file_bytes(&self) -> usize {
        HEADER_BYTES + self.payload.len() + TRAILER_BYTES
    }
}

/// What the bytes at a block boundary hold.
#[derive(Debug)]
pub(super) enum Next<'a> {
    Block(RawBlock<'a>),
    /// No bytes left.
    Eof,
    /// The file stops inside a block: the writer was stopped mid-block.
    Cut,
}

/// A block that cannot be what the writer wrote.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub(super) enum FramingError {
    #[error("block header checksum mismatch: the recording is corrupted")]
    HeaderChecksum,
    #[error(
        "payload length {len} is over the {MAX_PAYLOAD_BYTES} byte limit: the recording is \
         corrupted"
    )]
    TooLong { len: u32 },
    /// The header (and so `kind` and `len`) is sound, the payload is not.
    #[error("payload checksum mismatch: the recording is corrupted")]
    PayloadChecksum { kind: u8, len: u32 },
}

fn le_u32(b: &[u8]) -> u32 {
    let mut a = [0; 4];
    a.copy_from_slice(&b[..4]);
    u32::from_le_bytes(a)
}

/// The block at the start of `rest`.
pub(super) fn next_block(rest: &[u8]) -> Result<Next<'_>, FramingError> {
    if rest.is_empty() {
        return Ok(Next::Eof);
    }
    if rest.len() < HEADER_BYTES {
        return Ok(Next::Cut);
    }
    let (head, crc) = rest[..HEADER_BYTES].split_at(HEADER_BYTES - 4);
    if crc32fast::hash(head) != le_u32(crc) {
        return Err(FramingError::HeaderChecksum);
    }
    let seq = le_u32(&head[0..4]);
    let kind = head[4];
    let len = le_u32(&head[5..9]);
    if len > MAX_PAYLOAD_BYTES {
        return Err(FramingError::TooLong { len });
    }
    // `len` is at most 64 MiB: no overflow on any platform this runs on.
    let end = HEADER_BYTES + len as usize;
    if rest.len() < end + TRAILER_BYTES {
        return Ok(Next::Cut);
    }
    let payload = &rest[HEADER_BYTES..end];
    if crc32fast::hash(payload) != le_u32(&rest[end..end + TRAILER_BYTES]) {
        return Err(FramingError::PayloadChecksum { kind, len });
    }
    Ok(Next::Block(RawBlock { seq, kind, payload }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block(seq: u32, payload: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        encode(
            seq,
            BlockKind::Frames,
            &[&payload[..1], &payload[1..]],
            &mut out,
        )
        .expect("fits");
        out
    }

    #[test]
    fn a_block_reads_back_and_its_parts_are_one_payload() {
        let b = block(7, b"hello");
        assert_eq!(b.len(), HEADER_BYTES + 5 + TRAILER_BYTES);
        match next_block(&b) {
            Ok(Next::Block(r)) => {
                assert_eq!((r.seq, r.kind, r.payload), (7, 2, &b"hello"[..]));
                assert_eq!(r.file_bytes(), b.len());
            }
            other => panic!("{other:?}"),
        }
        assert!(matches!(next_block(&[]), Ok(Next::Eof)));
    }

    #[test]
    fn a_short_block_is_cut_and_a_bad_one_is_an_error() {
        let b = block(0, b"hello");
        for n in 1..b.len() {
            assert!(matches!(next_block(&b[..n]), Ok(Next::Cut)), "{n}");
        }
        let mut bad = b.clone();
        bad[6] ^= 0x40; // inside `len`
        assert_eq!(next_block(&bad).err(), Some(FramingError::HeaderChecksum));
        let mut bad = b.clone();
        bad[HEADER_BYTES + 1] ^= 1;
        assert_eq!(
            next_block(&bad).err(),
            Some(FramingError::PayloadChecksum { kind: 2, len: 5 })
        );
        // A length over the cap with a sound header checksum (a writer bug, or a forgery).
        let mut big = b[..9].to_vec();
        big[5..9].copy_from_slice(&(MAX_PAYLOAD_BYTES + 1).to_le_bytes());
        let crc = crc32fast::hash(&big);
        big.extend_from_slice(&crc.to_le_bytes());
        assert_eq!(
            next_block(&big).err(),
            Some(FramingError::TooLong {
                len: MAX_PAYLOAD_BYTES + 1
            })
        );
    }

    #[test]
    fn an_oversized_payload_is_refused_by_the_encoder() {
        let big = vec![0; MAX_PAYLOAD_BYTES as usize + 1];
        let mut out = Vec::new();
        let e = encode(0, BlockKind::Header, &[&big], &mut out).expect_err("too big");
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
    }
}
