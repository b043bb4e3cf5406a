//! The on-disk cache of a boundary-element precomputation: named arrays of f64 under a key
//! of everything they were computed from.
//!
//! Layout (little-endian): the magic `VESBEM\r\n`, the format version (u32), the key (u64),
//! the number of arrays (u32), then per array its name's length (u16), name (UTF-8), length
//! (u64) and values (f64); last, the CRC-32 of everything after the magic. A file is written
//! beside its final name and renamed over it, so a crash leaves the old file or the new one,
//! never half of one. A file whose magic, version, key or checksum does not match is reported
//! as such, and the caller rebuilds it.

use std::io::Write;
use std::path::{Path, PathBuf};

const MAGIC: &[u8; 8] = b"VESBEM\r\n";
/// Bumped whenever the layout or the meaning of what is cached changes.
pub const VERSION: u32 = 1;

/// Why a cache file was not used.
#[derive(Debug, thiserror::Error)]
pub enum CacheError {
    #[error("{path}: no cache yet")]
    Missing { path: PathBuf },
    #[error("{path}: cannot read or write the cache: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: not a cache file, or cut short")]
    Corrupt { path: PathBuf },
    #[error("{path}: written by cache format {found}, this build reads {expected}")]
    Version {
        path: PathBuf,
        found: u32,
        expected: u32,
    },
    #[error("{path}: computed for other inputs (key {found:016x}, wanted {expected:016x})")]
    Stale {
        path: PathBuf,
        found: u64,
        expected: u64,
    },
    #[error("{path}: checksum {found:08x} does not match the contents ({expected:08x})")]
    Checksum {
        path: PathBuf,
        found: u32,
        expected: u32,
    },
}

/// Named arrays.
pub type Arrays = Vec<(String, Vec<f64>)>;

/// Writes `arrays` under `key` to `path` (through a temporary file renamed over it: its own
/// for each call, so that two threads or processes writing the same cache at once each
/// leave a whole file, the last one's).
pub fn write(path: &Path, key: u64, arrays: &Arrays) -> Result<(), CacheError> {
    let io = |source| CacheError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut body: Vec<u8> = Vec::new();
    body.extend_from_slice(&VERSION.to_le_bytes());
    body.extend_from_slice(&key.to_le_bytes());
    body.extend_from_slice(&(arrays.len() as u32).to_le_bytes());
    for (name, values) in arrays {
        body.extend_from_slice(&(name.len() as u16).to_le_bytes());
        body.extend_from_slice(name.as_bytes());
        body.extend_from_slice(&(values.len() as u64).to_le_bytes());
        body.reserve(8 * values.len());
        for v in values {
            body.extend_from_slice(&v.to_le_bytes());
        }
    }
    let crc = crc32fast::hash(&body);
    if let Some(dir) = path.parent()
        && !dir.as_os_str().is_empty()
    {
        std::fs::create_dir_all(dir).map_err(io)?;
    }
    let mut tmp = path.as_os_str().to_owned();
    static WRITES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = WRITES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    tmp.push(format!(".{}-{n}.tmp", std::process::id()));
    let tmp = PathBuf::from(tmp);
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(MAGIC)?;
        f.write_all(&body)?;
        f.write_all(&crc.to_le_bytes())?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(io)
}

/// Reads the arrays cached at `path` for `key`.
pub fn read(path: &Path, key: u64) -> Result<Arrays, CacheError> {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(CacheError::Missing {
                path: path.to_path_buf(),
            });
        }
        Err(source) => {
            return Err(CacheError::Io {
                path: path.to_path_buf(),
                source,
            });
        }
    };
    let corrupt = || CacheError::Corrupt {
        path: path.to_path_buf(),
    };
    if bytes.len() < MAGIC.len() + 4 + 8 + 4 + 4 || &bytes[..8] != MAGIC {
        return Err(corrupt());
    }
    let body = &bytes[8..bytes.len() - 4];
    let mut r = Reader { at: 0, b: body };
    let version = r.u32().ok_or_else(corrupt)?;
    if version != VERSION {
        return Err(CacheError::Version {
            path: path.to_path_buf(),
            found: version,
            expected: VERSION,
        });
    }
    let found = r.u64().ok_or_else(corrupt)?;
    if found != key {
        return Err(CacheError::Stale {
            path: path.to_path_buf(),
            found,
            expected: key,
        });
    }
    let mut tail = [0u8; 4];
    tail.copy_from_slice(&bytes[bytes.len() - 4..]);
    let stored = u32::from_le_bytes(tail);
    let crc = crc32fast::hash(body);
    if crc != stored {
        return Err(CacheError::Checksum {
            path: path.to_path_buf(),
            found: stored,
            expected: crc,
        });
    }
    let count = r.u32().ok_or_else(corrupt)?;
    let mut arrays = Vec::new();
    for _ in 0..count {
        let len = r.u16().ok_or_else(corrupt)? as usize;
        let name = r.take(len).ok_or_else(corrupt)?;
        let name = String::from_utf8(name.to_vec()).map_err(|_| corrupt())?;
        let n = r.u64().ok_or_else(corrupt)?;
        let n = usize::try_from(n).map_err(|_| corrupt())?;
        let raw = r
            .take(n.checked_mul(8).ok_or_else(corrupt)?)
            .ok_or_else(corrupt)?;
        let values = raw
            .chunks_exact(8)
            .map(|c| {
                let mut a = [0u8; 8];
                a.copy_from_slice(c);
                f64::from_le_bytes(a)
            })
            .collect();
        arrays.push((name, values));
    }
    if r.at != body.len() {
        return Err(corrupt());
    }
    Ok(arrays)
}

struct Reader<'a> {
    at: usize,
    b: &'a [u8],
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Option<&[u8]> {
        let end = self.at.checked_add(n)?;
        let s = self.b.get(self.at..end)?;
        self.at = end;
        Some(s)
    }
    fn u16(&mut self) -> Option<u16> {
        self.take(2).map(|s| u16::from_le_bytes([s[0], s[1]]))
    }
    fn u32(&mut self) -> Option<u32> {
        let s = self.take(4)?;
        Some(u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
    }
    fn u64(&mut self) -> Option<u64> {
        let s = self.take(8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(s);
        Some(u64::from_le_bytes(a))
    }
}

/// A key over f64 and integer inputs: FNV-1a, 64 bits.
#[derive(Debug, Clone, Copy)]
pub struct Key(pub u64);

impl Default for Key {
    fn default() -> Key {
        Key(0xcbf2_9ce4_8422_2325)
    }
}

impl Key {
    pub fn bytes(&mut self, b: &[u8]) {
        for &x in b {
            self.0 ^= u64::from(x);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    pub fn f64(&mut self, v: f64) {
        self.bytes(&v.to_bits().to_le_bytes());
    }
    pub fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }
}

/// Where precomputations are kept: `$VESALIUS_CACHE_DIR`, else `$XDG_CACHE_HOME/vesalius`,
/// else `$HOME/.cache/vesalius`, else `vesalius-cache` in the working folder.
pub fn default_dir() -> PathBuf {
    let var = |k: &str| {
        std::env::var_os(k)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    if let Some(d) = var("VESALIUS_CACHE_DIR") {
        return d;
    }
    if let Some(d) = var("XDG_CACHE_HOME") {
        return d.join("vesalius");
    }
    if let Some(h) = var("HOME") {
        return h.join(".cache").join("vesalius");
    }
    PathBuf::from("vesalius-cache")
}
