//! Where the ONNX Runtime shared library comes from.
//!
//! The library is loaded at run time (`ort`'s `load-dynamic`): nothing is downloaded or linked at
//! build time. It is found, in this order:
//! 1. `ORT_DYLIB_PATH`: the path of a `libonnxruntime.so.<version>` (any build, e.g. a robot's
//!    own);
//! 2. the `onnxruntime` (or `onnxruntime-gpu`) wheel of the machine's `python3` (`python3 -m pip
//!    install onnxruntime`): its `onnxruntime/capi/libonnxruntime.so.<version>` (the wheel ships
//!    no unversioned symlink), the newest when there are several. The GPU wheel's CUDA and
//!    TensorRT providers sit beside it and are found by ONNX Runtime itself.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The environment variable naming the library.
pub const DYLIB_PATH_VAR: &str = "ORT_DYLIB_PATH";

/// What to do when no library is found.
pub const INSTALL_HINT: &str = "install ONNX Runtime with `python3 -m pip install onnxruntime` \
     (GPU: `onnxruntime-gpu`, see docs/operating.md) or set ORT_DYLIB_PATH to a \
     libonnxruntime.so.<version>";

/// How the library was found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LibrarySource {
    /// `ORT_DYLIB_PATH`.
    Environment,
    /// The `onnxruntime` wheel of `python3`, in this package directory.
    PythonWheel { package_dir: PathBuf },
}

/// Finds the library; the error says what was tried.
pub fn find_library() -> Result<(PathBuf, LibrarySource), String> {
    if let Some(path) = std::env::var_os(DYLIB_PATH_VAR).filter(|p| !p.is_empty()) {
        let path = PathBuf::from(path);
        return if path.is_file() {
            Ok((path, LibrarySource::Environment))
        } else {
            Err(format!("{DYLIB_PATH_VAR}={} is not a file", path.display()))
        };
    }
    let package_dir = python_package_dir().map_err(|reason| {
        format!("{DYLIB_PATH_VAR} is not set and python3 has no onnxruntime package ({reason})")
    })?;
    let capi = package_dir.join("capi");
    match newest_library(&capi) {
        Some(path) => Ok((path, LibrarySource::PythonWheel { package_dir })),
        None => Err(format!(
            "{DYLIB_PATH_VAR} is not set and {} holds no libonnxruntime.so.<version>",
            capi.display()
        )),
    }
}

/// The directory of python3's `onnxruntime` package.
fn python_package_dir() -> Result<PathBuf, String> {
    let output = Command::new("python3")
        .args([
            "-c",
            "import os, onnxruntime; print(os.path.dirname(onnxruntime.__file__))",
        ])
        .output()
        .map_err(|error| format!("python3 not run: {error}"))?;
    if !output.status.success() {
        let stderr = String::from_utf8_lossy(&output.stderr);
        let last = stderr.lines().last().unwrap_or("").trim().to_string();
        return Err(last);
    }
    let dir = String::from_utf8_lossy(&output.stdout).trim().to_string();
    if dir.is_empty() {
        return Err("no package directory printed".to_string());
    }
    Ok(PathBuf::from(dir))
}

/// The `libonnxruntime.so.<version>` with the highest version in `dir` (the unversioned name
/// counts as the lowest).
pub fn newest_library(dir: &Path) -> Option<PathBuf> {
    let entries = std::fs::read_dir(dir).ok()?;
    entries
        .filter_map(|entry| {
            let name = entry.ok()?.file_name().into_string().ok()?;
            let version = name.strip_prefix("libonnxruntime.so")?;
            let version: Vec<u32> = if version.is_empty() {
                Vec::new()
            } else {
                version
                    .strip_prefix('.')?
                    .split('.')
                    .map(|part| part.parse().ok())
                    .collect::<Option<_>>()?
            };
            Some((version, name))
        })
        .max()
        .map(|(_, name)| dir.join(name))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_newest_versioned_library_is_chosen() {
        let dir = std::env::temp_dir().join(format!("harvest-ort-lookup-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        for name in [
            "libonnxruntime.so.1.9.0",
            "libonnxruntime.so.1.31.1",
            "libonnxruntime.so",
            "libonnxruntime_providers_shared.so",
            "libonnxruntime.so.1.31.1.bak",
        ] {
            std::fs::write(dir.join(name), b"").expect("write");
        }
        assert_eq!(
            newest_library(&dir),
            Some(dir.join("libonnxruntime.so.1.31.1"))
        );
        assert_eq!(newest_library(&dir.join("missing")), None);
        std::fs::remove_dir_all(&dir).expect("clean up");
    }
}
