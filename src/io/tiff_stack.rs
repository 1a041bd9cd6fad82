//! TIFF stacks: one page per z slice, 8-bit grey (one channel), RGB (three) or RGBA (two, grey
//! replicated, or four), uncompressed, written slab by slab. The first page carries ImageJ's
//! description (`images=`/`slices=`), so Fiji and ImageJ open the file as a z stack; tifffile,
//! napari and ParaView read the pages in order. A stack over 4 GiB is written as BigTIFF.

use crate::error::{Error, Result};
use crate::io::atomic::PendingFile;
use crate::io::slab_order::SlabOrder;
use crate::volume::Volume;
use std::path::{Path, PathBuf};
use tiff::encoder::{colortype, TiffEncoder, TiffKind, TiffKindBig, TiffKindStandard};
use tiff::tags::Tag;

/// Classic TIFF addresses 4 GiB; larger stacks (with room for the directories) use BigTIFF.
const CLASSIC_LIMIT: u64 = (4 << 30) - (64 << 20);

enum Encoder {
    Standard(TiffEncoder<std::fs::File, TiffKindStandard>),
    Big(TiffEncoder<std::fs::File, TiffKindBig>),
}

/// A stack written slab by slab along z; atomic as [`crate::io::nrrd::SlabWriter`].
pub struct SlabWriter {
    file: PendingFile,
    encoder: Encoder,
    path: PathBuf,
    order: SlabOrder,
}

/// ImageJ's description of a z stack of `slices` pages.
pub fn imagej_description(slices: u32) -> String {
    format!("ImageJ=1.11a\nimages={slices}\nslices={slices}\nloop=false\n")
}

fn tiff_error(path: &Path, e: tiff::TiffError) -> Error {
    match e {
        tiff::TiffError::IoError(io) => Error::io(path, io),
        other => Error::Internal(format!(
            "TIFF encoding of {} failed: {other}",
            path.display()
        )),
    }
}

impl SlabWriter {
    pub fn create(path: &Path, dims: [u32; 3], channels: u32) -> Result<SlabWriter> {
        let mut file = PendingFile::create(path)?;
        // The encoder writes through its own handle of the same open file (one file offset).
        let handle = file
            .file_mut()
            .try_clone()
            .map_err(|e| Error::io(path, e))?;
        let stored = if channels == 1 {
            1
        } else if channels == 3 {
            3
        } else {
            4
        };
        let bytes = dims.iter().map(|&d| d as u64).product::<u64>() * stored;
        let encoder = if bytes > CLASSIC_LIMIT {
            Encoder::Big(TiffEncoder::new_big(handle).map_err(|e| tiff_error(path, e))?)
        } else {
            Encoder::Standard(TiffEncoder::new(handle).map_err(|e| tiff_error(path, e))?)
        };
        Ok(SlabWriter {
            file,
            encoder,
            path: path.to_path_buf(),
            order: SlabOrder::new(dims, channels)?,
        })
    }

    /// The next `slab.nz` z slices, a page each.
    pub fn write_slab(&mut self, slab: &Volume) -> Result<()> {
        let first_slice = self.order.slices_written();
        self.order.advance(slab)?;
        let slice_len = slab.nx as usize * slab.ny as usize * slab.channels as usize;
        for (k, page) in slab.data.chunks_exact(slice_len).enumerate() {
            let first = first_slice + k as u32 == 0;
            let [w, h, depth] = self.order.dims();
            let channels = self.order.channels();
            let description = first.then(|| imagej_description(depth));
            let result = match &mut self.encoder {
                Encoder::Standard(e) => write_page(e, w, h, channels, page, description),
                Encoder::Big(e) => write_page(e, w, h, channels, page, description),
            };
            result.map_err(|e| tiff_error(&self.path, e))?;
        }
        Ok(())
    }

    pub fn finish(self) -> Result<PendingFile> {
        self.order.finish()?;
        drop(self.encoder);
        Ok(self.file)
    }
}

/// The stack of `v` in memory (the server's downloads).
pub fn to_bytes(v: &Volume) -> Result<Vec<u8>> {
    let mut cursor = std::io::Cursor::new(Vec::new());
    let path = Path::new("volume.tif");
    let mut encoder = TiffEncoder::new(&mut cursor).map_err(|e| tiff_error(path, e))?;
    crate::io::slab_order::check_dims(v.dims(), v.channels)?;
    v.check("volume")?;
    let slice_len = v.nx as usize * v.ny as usize * v.channels as usize;
    for (z, page) in v.data.chunks_exact(slice_len).enumerate() {
        let description = (z == 0).then(|| imagej_description(v.nz));
        write_page(&mut encoder, v.nx, v.ny, v.channels, page, description)
            .map_err(|e| tiff_error(path, e))?;
    }
    Ok(cursor.into_inner())
}

fn write_page<W: std::io::Write + std::io::Seek, K: TiffKind>(
    encoder: &mut TiffEncoder<W, K>,
    width: u32,
    height: u32,
    channels: u32,
    page: &[u8],
    description: Option<String>,
) -> tiff::TiffResult<()> {
    macro_rules! page {
        ($color:ty, $data:expr) => {{
            let mut image = encoder.new_image::<$color>(width, height)?;
            if let Some(text) = &description {
                image
                    .encoder()
                    .write_tag(Tag::ImageDescription, text.as_str())?;
            }
            image.write_data($data)
        }};
    }
    match channels {
        1 => page!(colortype::Gray8, page),
        3 => page!(colortype::RGB8, page),
        4 => page!(colortype::RGBA8, page),
        _ => {
            let rgba: Vec<u8> = page
                .chunks_exact(2)
                .flat_map(|p| [p[0], p[0], p[0], p[1]])
                .collect();
            page!(colortype::RGBA8, &rgba)
        }
    }
}
