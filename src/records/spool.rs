//! Sessions waiting to be stored: when the records cannot be reached (a centre's server down
//! longer than the retries last), the session's output folder, which holds all of it, is
//! listed here with its trainee, and `vesalius records sync` stores what is listed later. The
//! list is a text file (`folder<TAB>trainee` a line), rewritten whole and renamed into place.

use super::{Db, RecordsError};
use std::path::{Path, PathBuf};

/// The list: `$VESALIUS_SPOOL`, else `$XDG_DATA_HOME/vesalius/pending-records.txt`, else
/// `~/.local/share/vesalius/pending-records.txt`.
pub fn path() -> PathBuf {
    if let Some(p) = std::env::var_os("VESALIUS_SPOOL") {
        return PathBuf::from(p);
    }
    let data = std::env::var_os("XDG_DATA_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".local/share")))
        .unwrap_or_else(|| PathBuf::from("."));
    data.join("vesalius").join("pending-records.txt")
}

fn io(p: &Path) -> impl Fn(std::io::Error) -> RecordsError + '_ {
    move |source| RecordsError::Io {
        path: p.display().to_string(),
        source,
    }
}

/// What the list at `list` holds: (folder, trainee) pairs.
pub fn pending(list: &Path) -> Result<Vec<(PathBuf, String)>, RecordsError> {
    let text = match std::fs::read_to_string(list) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(io(list)(e)),
    };
    Ok(text
        .lines()
        .filter_map(|l| l.split_once('\t'))
        .map(|(d, t)| (PathBuf::from(d), t.to_string()))
        .collect())
}

fn write(list: &Path, items: &[(PathBuf, String)]) -> Result<(), RecordsError> {
    if let Some(dir) = list.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(io(dir))?;
    }
    let text: String = items
        .iter()
        .map(|(d, t)| format!("{}\t{t}\n", d.display()))
        .collect();
    let tmp = list.with_extension("txt.partial");
    std::fs::write(&tmp, text).map_err(io(&tmp))?;
    std::fs::rename(&tmp, list).map_err(io(list))
}

/// Lists `dir` (made absolute) for `trainee`, once.
pub fn add(list: &Path, dir: &Path, trainee: &str) -> Result<(), RecordsError> {
    let dir = std::path::absolute(dir).map_err(io(dir))?;
    let mut items = pending(list)?;
    if !items.iter().any(|(d, t)| d == &dir && t == trainee) {
        items.push((dir, trainee.to_string()));
    }
    write(list, &items)
}

/// What a sync did: the ids stored, and the folders still listed with why.
pub type Synced = (Vec<String>, Vec<(PathBuf, String)>);

/// Stores what is listed into `db`; what still cannot be stored stays listed.
pub fn sync(list: &Path, db: &mut Db) -> Result<Synced, RecordsError> {
    let mut stored = Vec::new();
    let mut failed = Vec::new();
    let mut left = Vec::new();
    for (dir, trainee) in pending(list)? {
        match db.store_dir(&dir, &trainee) {
            Ok(id) => stored.push(id),
            Err(e) => {
                failed.push((dir.clone(), e.to_string()));
                left.push((dir, trainee));
            }
        }
    }
    write(list, &left)?;
    Ok((stored, failed))
}
