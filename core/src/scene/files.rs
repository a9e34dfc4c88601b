//! Where the loaders read files: the disk ([`Disk`]), or files held in memory (a
//! `HashMap<PathBuf, Vec<u8>>`), so that a scene can be loaded from bytes
//! ([`super::Scene::load_from`]) with the same checks and the same error messages, which
//! still name the file.
//!
//! Every file a scene refers to goes through one [`SceneFiles`]: the scene file itself, a
//! manifest's model files and environment map, a `.gltf` file's external buffers.

use std::collections::HashMap;
use std::io::{Error, ErrorKind};
use std::path::{Path, PathBuf};

/// A source of file contents.
pub trait SceneFiles {
    /// The whole content of the file at `path`.
    fn read(&self, path: &Path) -> std::io::Result<Vec<u8>>;
}

/// The file system. Only regular files are read: a device or a pipe (`/dev/zero` named as
/// a buffer, say) could be endless.
#[derive(Clone, Copy, Debug, Default)]
pub struct Disk;

impl SceneFiles for Disk {
    fn read(&self, path: &Path) -> std::io::Result<Vec<u8>> {
        if !std::fs::metadata(path)?.is_file() {
            return Err(Error::new(ErrorKind::InvalidInput, "not a regular file"));
        }
        std::fs::read(path)
    }
}

/// Files in memory, by the exact path a loader asks for; any other path is not found.
impl SceneFiles for HashMap<PathBuf, Vec<u8>> {
    fn read(&self, path: &Path) -> std::io::Result<Vec<u8>> {
        self.get(path).cloned().ok_or_else(|| Error::new(ErrorKind::NotFound, "no such file (in memory)"))
    }
}

/// A budget of bytes a loader may allocate for what it builds from a file (decoded vertices
/// and indices, objects), so that a small file cannot make it allocate without bound: a few
/// hundred bytes of glTF JSON can instance one mesh of many primitives from many nodes, or
/// give an accessor without a buffer view (all zeros) any count.
#[derive(Debug)]
pub(crate) struct Budget {
    left: usize,
}

impl Budget {
    /// Bytes every load may use whatever its input's size: room for all-zero accessors and
    /// built-in shapes of a small file (the largest built-in, the 48 x 24 sphere, is about
    /// 40 KiB).
    const BASE_BYTES: usize = 64 << 20;

    /// Bytes per input byte: decoding widens 8-bit indices to 32 bits (4x) and adds a
    /// `0..n` index list to a primitive without indices (a third of its positions' bytes);
    /// 16 leaves room for a few primitives sharing one accessor, as exporters write. A file
    /// whose accessors are each read once stays under 4 (the assets of `shared/assets`).
    const BYTES_PER_INPUT_BYTE: usize = 16;

    /// The budget for a load whose inputs hold `input_bytes`.
    pub(crate) fn for_input(input_bytes: usize) -> Budget {
        Budget { left: Self::BASE_BYTES.saturating_add(input_bytes.saturating_mul(Self::BYTES_PER_INPUT_BYTE)) }
    }

    /// Take `count` items of `item_bytes` each from the budget, or say why not.
    pub(crate) fn take(&mut self, count: usize, item_bytes: usize, what: &str) -> Result<(), String> {
        match count.checked_mul(item_bytes) {
            Some(bytes) if bytes <= self.left => {
                self.left -= bytes;
                Ok(())
            }
            _ => Err(format!(
                "{what}: {count} items of {item_bytes} bytes exceed what the file can plausibly hold \
                 ({} bytes left of the load's budget: {} MiB plus {}x the input's size)",
                self.left,
                Self::BASE_BYTES >> 20,
                Self::BYTES_PER_INPUT_BYTE
            )),
        }
    }

    /// Bytes left.
    pub(crate) fn left(&self) -> usize {
        self.left
    }

    /// Add the bytes of a further input (a buffer, a model file) to the budget.
    pub(crate) fn add_input(&mut self, input_bytes: usize) {
        self.left = self.left.saturating_add(input_bytes.saturating_mul(Self::BYTES_PER_INPUT_BYTE));
    }
}
