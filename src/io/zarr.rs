//! Zarr v3 arrays on a file system (<https://zarr-specs.readthedocs.io/en/latest/v3/core/index.html>),
//! written chunk by chunk: a volume as a `uint8` array of shape (Z, Y, X, C), cut into cubic
//! chunks of `c` voxels (chunk shape (c, c, c, C)). The array is a directory: `zarr.json` (the
//! metadata: regular chunk grid, the `default` chunk key encoding with separator `/`, fill value
//! 0, the one codec `bytes`, which for a one-byte type needs no `endian`) and one file per chunk
//! at `c/IZ/IY/IX/0`, holding the chunk's c * c * c * C bytes in C order (channel fastest, then x,
//! y, z: the NRRD order). Chunks at the far edges are full-size like every other (the spec's
//! regular grid); their voxels past the array's end are 0.
//!
//! Each chunk is written to a temporary file beside it and renamed into place (see
//! [`crate::io::atomic`]), so a chunk file present is a complete one: an interrupted writer loses
//! the chunks it was writing, never one it finished, and a later writer completes the array by
//! skipping the chunks present ([`chunk_is_complete`]). Several processes may fill one array
//! together: each writes the same `zarr.json` bytes without replacing one already there
//! ([`open`]), and chunks are theirs alone. Written here rather than through a crate: the
//! metadata are one JSON document and a chunk is raw bytes.

use crate::error::{Error, Result};
use crate::io::atomic;
use serde::Serialize;
use serde_json::Value;
use std::path::{Path, PathBuf};

/// The array's metadata document, at its root.
pub const METADATA_FILE: &str = "zarr.json";

/// How the temporaries of [`crate::io::atomic`] (and ours) are named: tolerated inside an
/// array, where another writer may be about to rename one into place.
const TEMPORARY_PREFIX: &str = ".solidsynth-";
const TEMPORARY_SUFFIX: &str = ".partial";

/// The array's geometry: a volume of `dims` voxels (x, y, z) with `channels` bytes a voxel, in
/// cubic chunks of `chunk` voxels. Made by [`Layout::new`], which checks it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    dims: [u32; 3],
    channels: u32,
    chunk: u32,
}

/// Largest chunk edge a layout takes: a chunk is one file held whole in memory (1024^3 voxels of
/// 4 bytes: 4 GiB).
pub const MAX_CHUNK: u32 = 1024;

impl Layout {
    /// The layout of a `dims` volume of `channels` (1 to 4) bytes a voxel in chunks of `chunk`
    /// (1..=[`MAX_CHUNK`]) voxels a side; an error naming the value that is out of range.
    pub fn new(dims: [u32; 3], channels: u32, chunk: u32) -> Result<Layout> {
        crate::io::slab_order::check_dims(dims, channels)?;
        if !(1..=MAX_CHUNK).contains(&chunk) {
            return Err(Error::invalid(
                format!("chunk {chunk}"),
                format!("must be 1..={MAX_CHUNK} voxels"),
            ));
        }
        Ok(Layout {
            dims,
            channels,
            chunk,
        })
    }

    /// The volume's size in voxels (x, y, z).
    pub fn dims(&self) -> [u32; 3] {
        self.dims
    }

    /// Bytes a voxel.
    pub fn channels(&self) -> u32 {
        self.channels
    }

    /// The chunk edge in voxels.
    pub fn chunk(&self) -> u32 {
        self.chunk
    }

    /// The array's shape, (Z, Y, X, C).
    pub fn shape(&self) -> [u64; 4] {
        let [x, y, z] = self.dims.map(u64::from);
        [z, y, x, self.channels as u64]
    }

    /// Chunks along z, y and x.
    pub fn grid(&self) -> [u64; 3] {
        let c = self.chunk as u64;
        let [x, y, z] = self.dims.map(u64::from);
        [z.div_ceil(c), y.div_ceil(c), x.div_ceil(c)]
    }

    /// Chunks in the array.
    pub fn chunk_count(&self) -> u64 {
        self.grid().iter().fold(1u64, |n, &g| n.saturating_mul(g))
    }

    /// Bytes of every chunk file (edge chunks included).
    pub fn chunk_bytes(&self) -> usize {
        (self.chunk as usize).pow(3) * self.channels as usize
    }

    /// The grid position (iz, iy, ix) of chunk `k` in C order (ix fastest): the index
    /// `--chunks-of I/N` shares out (chunk k goes to process k mod N).
    pub fn chunk_at(&self, k: u64) -> [u64; 3] {
        let [_, gy, gx] = self.grid();
        [k / (gy * gx), (k / gx) % gy, k % gx]
    }

    /// The voxels of the volume chunk `at` holds: its first voxel and its size (x, y, z),
    /// clipped to the volume (smaller than the chunk at the far edges).
    pub fn chunk_extent(&self, at: [u64; 3]) -> ([u32; 3], [u32; 3]) {
        let c = self.chunk as u64;
        let lo = [at[2], at[1], at[0]].map(|i| i * c);
        let size = [0, 1, 2].map(|a| (self.dims[a] as u64 - lo[a]).min(c) as u32);
        (lo.map(|v| v as u32), size)
    }
}

/// `{"name": ..., "configuration": ...}`, the shape of every extension point of the metadata.
#[derive(Serialize)]
struct Named<C: Serialize> {
    name: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    configuration: Option<C>,
}

#[derive(Serialize)]
struct RegularGrid {
    chunk_shape: [u64; 4],
}

#[derive(Serialize)]
struct KeySeparator {
    separator: &'static str,
}

/// `zarr.json`, its keys in the spec's order.
#[derive(Serialize)]
struct ArrayMetadata<'a> {
    zarr_format: u32,
    node_type: &'static str,
    shape: [u64; 4],
    data_type: &'static str,
    chunk_grid: Named<RegularGrid>,
    chunk_key_encoding: Named<KeySeparator>,
    fill_value: u8,
    codecs: [Named<()>; 1],
    dimension_names: [&'static str; 4],
    attributes: &'a Value,
}

/// The bytes of `zarr.json` for `layout` with `attributes` (a JSON object; the writers of one
/// array must give the same, so nothing of one process belongs in it). Deterministic: the same
/// layout and attributes give the same bytes.
pub fn metadata(layout: &Layout, attributes: &Value) -> Vec<u8> {
    let c = layout.chunk as u64;
    let document = ArrayMetadata {
        zarr_format: 3,
        node_type: "array",
        shape: layout.shape(),
        data_type: "uint8",
        chunk_grid: Named {
            name: "regular",
            configuration: Some(RegularGrid {
                chunk_shape: [c, c, c, layout.channels as u64],
            }),
        },
        chunk_key_encoding: Named {
            name: "default",
            configuration: Some(KeySeparator { separator: "/" }),
        },
        fill_value: 0,
        codecs: [Named {
            name: "bytes",
            configuration: None,
        }],
        dimension_names: ["z", "y", "x", "c"],
        attributes,
    };
    let mut bytes = serde_json::to_vec_pretty(&document).expect("the metadata serialize");
    bytes.push(b'\n');
    bytes
}

/// The store key of chunk `at` (iz, iy, ix): the `default` encoding, channels in one chunk.
pub fn chunk_key(at: [u64; 3]) -> String {
    format!("c/{}/{}/{}/0", at[0], at[1], at[2])
}

/// The file of chunk `at` in the array at `root`.
pub fn chunk_path(root: &Path, at: [u64; 3]) -> PathBuf {
    let mut path = root.to_path_buf();
    path.extend(chunk_key(at).split('/'));
    path
}

/// Whether the file of chunk `at` is there (complete or not: our files are complete once there).
pub fn chunk_exists(root: &Path, at: [u64; 3]) -> bool {
    std::fs::symlink_metadata(chunk_path(root, at)).is_ok()
}

/// Whether chunk `at` is there with its full size: a writer that resumes skips it.
pub fn chunk_is_complete(root: &Path, at: [u64; 3], bytes: usize) -> bool {
    std::fs::metadata(chunk_path(root, at)).is_ok_and(|m| m.is_file() && m.len() == bytes as u64)
}

/// Write chunk `at` atomically (complete or absent, even across a power loss: the directories
/// it creates are synced into their parents).
pub fn write_chunk(root: &Path, at: [u64; 3], data: &[u8]) -> Result<()> {
    let path = chunk_path(root, at);
    ensure_dir(atomic::parent_dir(&path))?;
    atomic::write_file(&path, data)
}

/// Create `dir` and the missing directories above it, syncing each new one's parent.
fn ensure_dir(dir: &Path) -> Result<()> {
    if dir.is_dir() {
        return Ok(());
    }
    if let Some(parent) = dir.parent().filter(|p| !p.as_os_str().is_empty()) {
        ensure_dir(parent)?;
    }
    match std::fs::create_dir(dir) {
        Ok(()) => atomic::sync_dir(atomic::parent_dir(dir)),
        // Another writer of the array made it meanwhile.
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && dir.is_dir() => Ok(()),
        Err(e) => Err(Error::io(dir, e)),
    }
}

/// How [`open`] found the array.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Opened {
    /// This call wrote `zarr.json` (the path was new or an empty directory).
    Created,
    /// An array with the same metadata was there (or another writer made it meanwhile).
    Joined,
}

/// Refuse a path that cannot become or be this array, before any work and writing nothing:
/// anything but a new path, an empty directory, or (when `may_join`: completing an array or
/// filling it with other processes) a directory holding a `zarr.json`, or one holding only
/// another writer's temporaries. A `zarr.json` there is compared by [`open`].
pub fn check_target(root: &Path, flag: &str, may_join: bool) -> Result<()> {
    let what = || format!("{flag} {}", root.display());
    if std::fs::symlink_metadata(root).is_err() {
        return atomic::check_output_dir(root, flag);
    }
    if !root.is_dir() {
        return Err(Error::invalid(
            what(),
            "exists and is not a directory (a Zarr array is one; nothing is overwritten)",
        ));
    }
    if root.join(METADATA_FILE).exists() {
        if !may_join {
            return Err(already_there(what()));
        }
        return Ok(());
    }
    let entries = std::fs::read_dir(root).map_err(|e| Error::io(root, e))?;
    for entry in entries {
        let name = entry.map_err(|e| Error::io(root, e))?.file_name();
        let name = name.to_string_lossy();
        if !(name.starts_with(TEMPORARY_PREFIX) && name.ends_with(TEMPORARY_SUFFIX)) {
            return Err(Error::invalid(
                what(),
                format!(
                    "exists and is neither an empty directory nor a Zarr array (it holds \
                     {name}); nothing is overwritten"
                ),
            ));
        }
    }
    Ok(())
}

fn already_there(what: String) -> Error {
    Error::invalid(
        what,
        "holds a Zarr array already (nothing is overwritten): --resume completes it, \
         --chunks-of I/N fills it together with other processes",
    )
}

/// Make the array at `root` with `metadata` ([`metadata`]'s bytes), or join the one there with
/// the same metadata when `may_join`. Never replaces what is there: `zarr.json` is put in place
/// only where none exists (so processes starting together on a new path all end up with the one
/// the first of them wrote, which they compare with theirs), and a different one is refused,
/// naming the first value that differs.
pub fn open(root: &Path, flag: &str, metadata: &[u8], may_join: bool) -> Result<Opened> {
    check_target(root, flag, may_join)?;
    match std::fs::create_dir(root) {
        Ok(()) => atomic::sync_dir(atomic::parent_dir(root))?,
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
        Err(e) => return Err(Error::io(root, e)),
    }
    let path = root.join(METADATA_FILE);
    if !path.exists() {
        if write_new(&path, metadata)? {
            return Ok(Opened::Created);
        }
        // Another process put its zarr.json in place between our look and our write.
        if !may_join {
            return Err(already_there(format!("{flag} {}", root.display())));
        }
    }
    let there = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
    compare(root, flag, metadata, &there)?;
    Ok(Opened::Joined)
}

/// Put `bytes` at `path` unless something is there already: false then (and nothing written).
fn write_new(path: &Path, bytes: &[u8]) -> Result<bool> {
    use std::io::Write;
    let dir = atomic::parent_dir(path);
    let mut builder = tempfile::Builder::new();
    builder.prefix(TEMPORARY_PREFIX).suffix(TEMPORARY_SUFFIX);
    // An ordinary file (0666 less the umask), not the temporary's private 0600.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let mut tmp = builder.tempfile_in(dir).map_err(|e| Error::io(dir, e))?;
    tmp.write_all(bytes)
        .and_then(|()| tmp.as_file().sync_all())
        .map_err(|e| Error::io(path, e))?;
    match tmp.persist_noclobber(path) {
        Ok(_) => {
            atomic::sync_dir(dir)?;
            Ok(true)
        }
        // The temporary is deleted with the error.
        Err(e) if e.error.kind() == std::io::ErrorKind::AlreadyExists => Ok(false),
        Err(e) => Err(Error::io(path, e.error)),
    }
}

/// Accept `there` (an existing `zarr.json`) when it is `ours` (byte for byte, or the same JSON
/// document formatted otherwise); else refuse, naming the first value that differs.
fn compare(root: &Path, flag: &str, ours: &[u8], there: &[u8]) -> Result<()> {
    if ours == there {
        return Ok(());
    }
    let what = format!("{flag} {}", root.display());
    let ours: Value = serde_json::from_slice(ours).expect("our metadata parse");
    let Ok(there) = serde_json::from_slice::<Value>(there) else {
        return Err(Error::invalid(
            what,
            format!("holds a {METADATA_FILE} that is not JSON (nothing is overwritten)"),
        ));
    };
    // The geometry first, then the attributes (the parsed documents' keys are sorted).
    let first = [
        "zarr_format",
        "node_type",
        "shape",
        "data_type",
        "chunk_grid",
        "chunk_key_encoding",
        "fill_value",
        "codecs",
    ]
    .into_iter()
    .find_map(|key| difference(&ours[key], &there[key], key));
    match first.or_else(|| difference(&ours, &there, "")) {
        None => Ok(()),
        Some((key, theirs, mine)) => Err(Error::invalid(
            what,
            format!(
                "holds another array: {key} is {theirs} there, {mine} for this command (nothing \
                 is overwritten: give the box and settings it was made with, or another path)"
            ),
        )),
    }
}

/// The first key (dotted path) where `there` differs from `ours`, with both values as text.
fn difference(ours: &Value, there: &Value, at: &str) -> Option<(String, String, String)> {
    let join = |key: &str| {
        if at.is_empty() {
            key.to_string()
        } else {
            format!("{at}.{key}")
        }
    };
    let text = |v: Option<&Value>| match v {
        None => "absent".to_string(),
        Some(v) => {
            let t = v.to_string();
            if t.chars().count() > 80 {
                format!("{}...", t.chars().take(77).collect::<String>())
            } else {
                t
            }
        }
    };
    match (ours, there) {
        (Value::Object(a), Value::Object(b)) => {
            for (key, mine) in a {
                match b.get(key) {
                    None => return Some((join(key), text(None), text(Some(mine)))),
                    Some(theirs) => {
                        if let Some(d) = difference(mine, theirs, &join(key)) {
                            return Some(d);
                        }
                    }
                }
            }
            b.iter()
                .find(|(key, _)| !a.contains_key(*key))
                .map(|(key, theirs)| (join(key), text(Some(theirs)), text(None)))
        }
        _ if ours == there => None,
        _ => Some((
            if at.is_empty() { "the document" } else { at }.to_string(),
            text(Some(there)),
            text(Some(ours)),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    const LAYOUT: Layout = Layout {
        dims: [40, 24, 32],
        channels: 3,
        chunk: 16,
    };

    #[test]
    fn the_metadata_are_a_zarr_v3_array_of_shape_zyxc() {
        let text = String::from_utf8(metadata(&LAYOUT, &json!({}))).unwrap();
        let expected = r#"{
  "zarr_format": 3,
  "node_type": "array",
  "shape": [
    32,
    24,
    40,
    3
  ],
  "data_type": "uint8",
  "chunk_grid": {
    "name": "regular",
    "configuration": {
      "chunk_shape": [
        16,
        16,
        16,
        3
      ]
    }
  },
  "chunk_key_encoding": {
    "name": "default",
    "configuration": {
      "separator": "/"
    }
  },
  "fill_value": 0,
  "codecs": [
    {
      "name": "bytes"
    }
  ],
  "dimension_names": [
    "z",
    "y",
    "x",
    "c"
  ],
  "attributes": {}
}
"#;
        assert_eq!(text, expected);
        // Attributes are carried as given, and the same input gives the same bytes.
        let attributes = json!({"solidsynth": {"seed": 5, "origin": [-7, 3, 5]}});
        let a = metadata(&LAYOUT, &attributes);
        assert_eq!(a, metadata(&LAYOUT, &attributes));
        let back: Value = serde_json::from_slice(&a).unwrap();
        assert_eq!(
            back["attributes"]["solidsynth"]["origin"],
            json!([-7, 3, 5])
        );
    }

    #[test]
    fn chunks_are_keyed_and_placed_in_c_order() {
        assert_eq!(LAYOUT.grid(), [2, 2, 3]);
        assert_eq!(LAYOUT.chunk_count(), 12);
        assert_eq!(LAYOUT.chunk_bytes(), 16 * 16 * 16 * 3);
        assert_eq!(LAYOUT.chunk_at(0), [0, 0, 0]);
        assert_eq!(LAYOUT.chunk_at(2), [0, 0, 2]);
        assert_eq!(LAYOUT.chunk_at(5), [0, 1, 2]);
        assert_eq!(LAYOUT.chunk_at(11), [1, 1, 2]);
        assert_eq!(chunk_key([1, 0, 2]), "c/1/0/2/0");
        assert_eq!(
            chunk_path(Path::new("out.zarr"), [1, 0, 2]),
            Path::new("out.zarr/c/1/0/2/0")
        );
        // Interior chunks are whole; the far ones are clipped to the volume (x: 40 = 16+16+8).
        assert_eq!(LAYOUT.chunk_extent([0, 0, 0]), ([0, 0, 0], [16, 16, 16]));
        assert_eq!(LAYOUT.chunk_extent([1, 1, 2]), ([32, 16, 16], [8, 8, 16]));
        let one = Layout {
            dims: [8, 8, 8],
            channels: 1,
            chunk: 16,
        };
        assert_eq!(
            (one.grid(), one.chunk_extent([0, 0, 0]).1),
            ([1; 3], [8; 3])
        );
    }

    #[test]
    fn an_array_is_created_once_joined_when_allowed_and_other_content_refused() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("a.zarr");
        let ours = metadata(&LAYOUT, &json!({"seed": 1}));
        assert_eq!(open(&root, "-o", &ours, false).unwrap(), Opened::Created);
        assert_eq!(std::fs::read(root.join(METADATA_FILE)).unwrap(), ours);
        // There now: refused unless joining, and then only with the same metadata.
        let e = open(&root, "-o", &ours, false).unwrap_err();
        assert!(
            e.is_user_error() && e.to_string().contains("--resume"),
            "{e}"
        );
        assert_eq!(open(&root, "-o", &ours, true).unwrap(), Opened::Joined);
        let wider = Layout {
            dims: [48, 24, 32],
            ..LAYOUT
        };
        let e = open(&root, "-o", &metadata(&wider, &json!({"seed": 1})), true).unwrap_err();
        assert!(
            e.to_string()
                .contains("shape is [32,24,40,3] there, [32,24,48,3] for"),
            "{e}"
        );
        let e = open(&root, "-o", &metadata(&LAYOUT, &json!({"seed": 2})), true).unwrap_err();
        assert!(
            e.to_string().contains("attributes.seed is 1 there, 2"),
            "{e}"
        );
        assert_eq!(std::fs::read(root.join(METADATA_FILE)).unwrap(), ours);
        // A directory of something else, or a file, is refused and left as it was.
        let other = dir.path().join("b.zarr");
        std::fs::create_dir(&other).unwrap();
        std::fs::write(other.join("notes.txt"), b"mine").unwrap();
        for join in [false, true] {
            assert!(open(&other, "-o", &ours, join).unwrap_err().is_user_error());
        }
        assert_eq!(std::fs::read_dir(&other).unwrap().count(), 1);
        let file = dir.path().join("c.zarr");
        std::fs::write(&file, b"x").unwrap();
        assert!(open(&file, "-o", &ours, true).unwrap_err().is_user_error());
        // An empty directory (or one holding only a writer's temporary) becomes the array.
        let empty = dir.path().join("d.zarr");
        std::fs::create_dir(&empty).unwrap();
        std::fs::write(empty.join(".solidsynth-x1y2.partial"), b"").unwrap();
        assert_eq!(open(&empty, "-o", &ours, false).unwrap(), Opened::Created);
    }

    #[test]
    fn a_chunk_is_complete_once_written_whole() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("a.zarr");
        let bytes = LAYOUT.chunk_bytes();
        assert!(!chunk_exists(&root, [1, 0, 2]));
        write_chunk(&root, [1, 0, 2], &vec![7; bytes]).unwrap();
        assert!(chunk_is_complete(&root, [1, 0, 2], bytes));
        assert_eq!(
            std::fs::read(root.join("c/1/0/2/0")).unwrap(),
            vec![7; bytes]
        );
        // Nothing else left in the chunk's directory; a short file is not complete.
        assert_eq!(std::fs::read_dir(root.join("c/1/0/2")).unwrap().count(), 1);
        std::fs::write(chunk_path(&root, [1, 0, 2]), b"short").unwrap();
        assert!(chunk_exists(&root, [1, 0, 2]));
        assert!(!chunk_is_complete(&root, [1, 0, 2], bytes));
    }
}
