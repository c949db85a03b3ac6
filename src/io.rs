//! Output files are written atomically: to a temporary file beside the target, flushed and
//! synced, then renamed over it. A failed or interrupted run leaves an existing output untouched
//! and no partial file under the target name (at worst a hidden `.name.*.tmp` beside it after a
//! SIGKILL, never the target itself half-written).
//!
//! ```
//! # let dir = tempfile::tempdir()?;
//! let path = dir.path().join("out.csv");
//! dynid::io::atomic_write(&path, |w| w.write_all(b"t,tau1\n0,1\n"))?;
//! assert_eq!(std::fs::read_to_string(&path)?, "t,tau1\n0,1\n");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Writing an output file failed; the target was not modified.
///
/// The I/O error is part of the message and deliberately not an error `source`: `{:#}` would
/// print it twice.
#[derive(Debug, thiserror::Error)]
#[error("{}: cannot write: {cause} — check that the directory is writable and the disk not full", path.display())]
pub struct WriteError {
    pub path: PathBuf,
    pub cause: std::io::Error,
}

/// Writes `path` atomically with the bytes produced by `write` (which gets a buffered writer).
/// If `write` fails, the error is returned and `path` is left as it was.
pub fn atomic_write<F>(path: &Path, write: F) -> Result<(), WriteError>
where
    F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
{
    let err = |cause| WriteError {
        path: path.to_path_buf(),
        cause,
    };
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    // `--out results/run1.csv` in a fresh checkout: make the directory, as `--out DIR` does.
    std::fs::create_dir_all(dir).map_err(err)?;
    let stem = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let prefix = format!(".{stem}.");
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(".tmp");
    // tempfile creates 0600 files; outputs are ordinary files (umask still applies).
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o644));
    }
    let tmp = builder.tempfile_in(dir).map_err(err)?;
    let mut out = BufWriter::new(tmp);
    write(&mut out).map_err(err)?;
    let tmp = out.into_inner().map_err(|e| err(e.into_error()))?;
    tmp.as_file().sync_all().map_err(err)?;
    // On error the temporary file is removed when `tmp` drops.
    tmp.persist(path).map_err(|e| err(e.error))?;
    Ok(())
}
