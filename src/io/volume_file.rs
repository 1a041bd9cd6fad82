//! Volume files chosen by the output's extension (or named by `--format`), written slab by slab
//! where the format allows it. One writer serves every command that writes a volume.
//!
//! | extension | format | written |
//! |---|---|---|
//! | `.nrrd` | NRRD, raw 8-bit, `sizes: C X Y Z` | streamed |
//! | (`--format nrrd-gzip`) | NRRD, its data gzip-compressed | streamed |
//! | `.npy` | NumPy, `uint8`, shape (Z, Y, X, C) | streamed |
//! | `.tif`, `.tiff` | TIFF stack, a page per z slice (ImageJ stack; BigTIFF over 4 GiB) | streamed |
//! | `.ktx2` | KTX2 3D texture, RGBA8 or R8 (sRGB and mips on request) | whole |
//! | `.vdb` | OpenVDB: `density` and `color` grids (Blender, Houdini, Unreal) | whole |
//! | `.vti` | VTK image data (ParaView) | whole |
//! | `.png` | flipbook: all z slices in one grid image (Unity, Unreal) | whole |

use crate::error::{Error, Result};
use crate::io::atomic::PendingFile;
use crate::io::{ktx2, npy, nrrd, tiff_stack, vdb};
use crate::volume::Volume;
use std::path::{Path, PathBuf};

/// A volume file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum VolumeFormat {
    Nrrd,
    /// NRRD with `encoding: gzip` (named by `--format`; `.nrrd` alone is raw).
    NrrdGzip,
    Npy,
    Tiff,
    Ktx2,
    Vdb,
    Vti,
    /// A flipbook PNG.
    Png,
}

/// The extensions known, for error messages.
pub const KNOWN_EXTENSIONS: &str = ".nrrd, .npy, .tif, .tiff, .ktx2, .vdb, .vti, .png";

impl VolumeFormat {
    /// The format `path`'s extension names; `what` names the path in the error (`-o`).
    pub fn from_path(path: &Path, what: &str) -> Result<VolumeFormat> {
        let extension = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match extension.as_deref() {
            Some("nrrd") => Ok(VolumeFormat::Nrrd),
            Some("npy") => Ok(VolumeFormat::Npy),
            Some("tif" | "tiff") => Ok(VolumeFormat::Tiff),
            Some("ktx2") => Ok(VolumeFormat::Ktx2),
            Some("vdb") => Ok(VolumeFormat::Vdb),
            Some("vti") => Ok(VolumeFormat::Vti),
            Some("png") => Ok(VolumeFormat::Png),
            Some(other) => Err(Error::invalid(
                format!("{what} {}", path.display()),
                format!(
                    "volumes cannot be written as .{other}; the extension picks the format: \
                     {KNOWN_EXTENSIONS} (or name one with --format)"
                ),
            )),
            None => Err(Error::invalid(
                format!("{what} {}", path.display()),
                format!(
                    "has no extension to pick the volume format by: {KNOWN_EXTENSIONS} (or name \
                     one with --format)"
                ),
            )),
        }
    }

    /// `format` when given, else the one `path`'s extension names.
    pub fn resolve(format: Option<VolumeFormat>, path: &Path, what: &str) -> Result<VolumeFormat> {
        match format {
            Some(f) => Ok(f),
            None => VolumeFormat::from_path(path, what),
        }
    }

    /// The format's name for messages.
    pub fn name(self) -> &'static str {
        match self {
            VolumeFormat::Nrrd => "NRRD",
            VolumeFormat::NrrdGzip => "gzip-compressed NRRD",
            VolumeFormat::Npy => "a NumPy array",
            VolumeFormat::Tiff => "a TIFF stack",
            VolumeFormat::Ktx2 => "a KTX2 texture",
            VolumeFormat::Vdb => "OpenVDB",
            VolumeFormat::Vti => "VTK image data",
            VolumeFormat::Png => "a PNG flipbook",
        }
    }

    /// Whether the writer holds the whole volume before writing (memory estimates count it).
    pub fn holds_whole_volume(self) -> bool {
        matches!(
            self,
            VolumeFormat::Ktx2 | VolumeFormat::Vdb | VolumeFormat::Vti | VolumeFormat::Png
        )
    }
}

/// How a volume is written: the format and its options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeOutput {
    pub format: VolumeFormat,
    /// KTX2 only: the sRGB formats and a mip chain.
    pub texture: ktx2::TextureOptions,
    /// OpenVDB only: the world size of a voxel and the world position of the volume's voxel
    /// (0, 0, 0) (commands give the box's low corner times the voxel size, so a region keeps
    /// its place in the infinite solid).
    pub vdb: vdb::VdbOptions,
}

impl VolumeOutput {
    /// The output `path` (named `what`) with an optional `--format` and texture options, the
    /// texture options refused for formats other than KTX2.
    pub fn resolve(
        path: &Path,
        what: &str,
        format: Option<VolumeFormat>,
        texture: ktx2::TextureOptions,
    ) -> Result<VolumeOutput> {
        let format = VolumeFormat::resolve(format, path, what)?;
        if format != VolumeFormat::Ktx2 && texture != ktx2::TextureOptions::default() {
            return Err(Error::invalid(
                "--srgb/--mips",
                format!(
                    "only KTX2 textures have them; {} is written as {}",
                    path.display(),
                    format.name()
                ),
            ));
        }
        Ok(VolumeOutput {
            format,
            texture,
            vdb: vdb::VdbOptions::default(),
        })
    }

    /// Refuse a volume of `dims` voxels this output cannot hold, before anything is computed.
    pub fn check(&self, path: &Path, dims: [u32; 3]) -> Result<()> {
        match self.format {
            VolumeFormat::Ktx2 => ktx2::check(dims, &format!("-o {}", path.display())),
            _ => Ok(()),
        }
    }
}

enum Target {
    Nrrd(nrrd::SlabWriter),
    Npy(npy::SlabWriter),
    Tiff(tiff_stack::SlabWriter),
    /// Formats written from the whole volume, at the end.
    Whole(Volume, crate::io::slab_order::SlabOrder),
}

/// A volume file written slab by slab along z: atomic (nothing at the path until the staged
/// file is committed; dropped before, nothing is left).
pub struct VolumeWriter {
    path: PathBuf,
    output: VolumeOutput,
    target: Target,
}

impl VolumeWriter {
    pub fn create(
        path: &Path,
        output: VolumeOutput,
        dims: [u32; 3],
        channels: u32,
    ) -> Result<VolumeWriter> {
        crate::io::slab_order::check_dims(dims, channels)?;
        output.check(path, dims)?;
        let target = match output.format {
            VolumeFormat::Nrrd | VolumeFormat::NrrdGzip => {
                Target::Nrrd(nrrd::SlabWriter::create_encoded(
                    path,
                    dims,
                    channels,
                    output.format == VolumeFormat::NrrdGzip,
                )?)
            }
            VolumeFormat::Npy => Target::Npy(npy::SlabWriter::create(path, dims, channels)?),
            VolumeFormat::Tiff => {
                Target::Tiff(tiff_stack::SlabWriter::create(path, dims, channels)?)
            }
            VolumeFormat::Ktx2 | VolumeFormat::Vdb | VolumeFormat::Vti | VolumeFormat::Png => {
                Target::Whole(
                    Volume::new(dims[0], dims[1], 0, channels),
                    crate::io::slab_order::SlabOrder::new(dims, channels)?,
                )
            }
        };
        Ok(VolumeWriter {
            path: path.to_path_buf(),
            output,
            target,
        })
    }

    /// The next `slab.nz` z slices.
    pub fn write_slab(&mut self, slab: &Volume) -> Result<()> {
        match &mut self.target {
            Target::Nrrd(w) => w.write_slab(slab),
            Target::Npy(w) => w.write_slab(slab),
            Target::Tiff(w) => w.write_slab(slab),
            Target::Whole(v, order) => {
                order.advance(slab)?;
                v.data.extend_from_slice(&slab.data);
                v.nz += slab.nz;
                Ok(())
            }
        }
    }

    /// The complete file, staged (to commit, or to stage with a command's other outputs).
    pub fn finish(self) -> Result<PendingFile> {
        match self.target {
            Target::Nrrd(w) => w.finish(),
            Target::Npy(w) => w.finish(),
            Target::Tiff(w) => w.finish(),
            Target::Whole(v, order) => {
                order.finish()?;
                let bytes = match self.output.format {
                    VolumeFormat::Ktx2 => ktx2::to_bytes(&v, self.output.texture)?,
                    VolumeFormat::Vdb => vdb::to_bytes(&v, self.output.vdb)?,
                    VolumeFormat::Vti => crate::io::vti::to_checked_bytes(&v, &self.path)?,
                    _ => crate::io::atomic::rgba_png_bytes(&crate::io::flipbook::to_image(&v))?,
                };
                let mut file = PendingFile::create(&self.path)?;
                file.write_all(&bytes)?;
                Ok(file)
            }
        }
    }
}

/// The file of `v` in `output`'s format, in memory (the server's downloads).
pub fn to_bytes(v: &Volume, output: VolumeOutput) -> Result<Vec<u8>> {
    crate::io::slab_order::check_dims(v.dims(), v.channels)?;
    v.check("volume")?;
    let mut bytes = match output.format {
        VolumeFormat::Nrrd => nrrd::header(v).into_bytes(),
        VolumeFormat::NrrdGzip => {
            let mut bytes = nrrd::header_encoded(v.dims(), v.channels, true).into_bytes();
            bytes.extend_from_slice(&nrrd::gzip_bytes(&v.data));
            return Ok(bytes);
        }
        VolumeFormat::Npy => npy::header(v.dims(), v.channels),
        VolumeFormat::Tiff => return tiff_stack::to_bytes(v),
        VolumeFormat::Ktx2 => return ktx2::to_bytes(v, output.texture),
        VolumeFormat::Vdb => return vdb::to_bytes(v, output.vdb),
        VolumeFormat::Vti => return crate::io::vti::to_bytes(v),
        VolumeFormat::Png => {
            return crate::io::atomic::rgba_png_bytes(&crate::io::flipbook::to_image(v));
        }
    };
    bytes.extend_from_slice(&v.data);
    Ok(bytes)
}

/// Write `v` to `path` in `output`'s format, atomically.
pub fn save(v: &Volume, path: &Path, output: VolumeOutput) -> Result<()> {
    let mut writer = VolumeWriter::create(path, output, v.dims(), v.channels)?;
    writer.write_slab(v)?;
    writer.finish()?.commit()
}
