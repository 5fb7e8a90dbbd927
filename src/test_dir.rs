//! Temporary directories for unit tests: each test gets a fresh one that is removed, with everything
//! in it, when the test ends, so runs leave nothing behind in the temp directory.

use std::path::{Path, PathBuf};

/// A fresh temporary directory, removed with everything in it when dropped.
pub(crate) struct TmpDir(PathBuf);

impl TmpDir {
    /// `<temp>/<name>_<pid>`, emptied if a previous run left it.
    pub(crate) fn new(name: &str) -> TmpDir {
        let d = std::env::temp_dir().join(format!("{name}_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("temp dir");
        TmpDir(d)
    }
}

impl Drop for TmpDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

impl std::ops::Deref for TmpDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}
