//! `region -o OUT.zarr`: the box as a chunked Zarr v3 array ([`crate::io::zarr`]), synthesized
//! chunk by chunk (each chunk its own request: any box equals the same voxels of any larger box)
//! so memory is one chunk's whatever the box's size; `--resume` skips the chunks already
//! written and `--chunks-of I/N` computes only chunks I, I + N, I + 2N, ..., so N processes on
//! any machines fill one array together.

use super::analyze::open_and_analyze;
use super::output::print_summary;
use super::synth::SolidArgs;
use crate::io::zarr::{self, Layout, Opened};
use crate::{Box3, Error, Solid};
use clap::Args;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The Zarr flags of `region` (flattened into its arguments).
#[derive(Args, Debug, Default)]
pub struct ZarrArgs {
    /// Zarr only: the edge of the array's cubic chunks, in voxels (8..=512, a multiple of 4;
    /// default 128). Each chunk is synthesized on its own, so memory is one chunk's whatever the
    /// box's size; smaller chunks recompute more dependency padding.
    #[arg(help_heading = "Output", long, value_name = "VOXELS")]
    pub chunk: Option<u32>,
    /// Zarr only: complete an existing array made by the same command: chunks already written
    /// are kept, only the missing ones are computed (after a crash or Ctrl-C, or a failed job).
    #[arg(help_heading = "Output", long)]
    pub resume: bool,
    /// Zarr only: compute only the chunks whose index (C order over z, y, x) is I modulo N,
    /// I = 0..N-1: N processes or machines given 0/N .. N-1/N fill one array together (on a
    /// shared file system; they may start together on a new path).
    #[arg(help_heading = "Output", long, value_name = "I/N")]
    pub chunks_of: Option<String>,
}

impl ZarrArgs {
    /// Refuse these flags for an output that is not a Zarr array.
    pub fn check_unused(&self) -> crate::Result<()> {
        for (flag, given) in [
            ("--chunk", self.chunk.is_some()),
            ("--resume", self.resume),
            ("--chunks-of", self.chunks_of.is_some()),
        ] {
            if given {
                return Err(Error::invalid(
                    flag,
                    "only Zarr outputs (-o NAME.zarr) are written in chunks",
                ));
            }
        }
        Ok(())
    }
}

/// The chunk edge when `--chunk` is not given.
pub const DEFAULT_CHUNK: u32 = 128;

/// Largest side of a chunked box: 65,536 voxels (about 2.8e14 voxels a cube, far past any
/// disk; the engine's coordinates reach +-2^28).
pub const MAX_ZARR_SIDE: i64 = 1 << 16;

/// Whether `-o` names a Zarr array: the extension `.zarr` (any case), `--format` not given.
pub fn is_zarr_output(args: &SolidArgs) -> bool {
    args.format.is_none()
        && args
            .output
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("zarr"))
}

/// Check `--chunk`: 8..=512 voxels and a multiple of the engine's brick edge (4), so chunks
/// boxes split no brick of a box whose corner is on the brick grid.
pub fn check_chunk(chunk: u32) -> crate::Result<u32> {
    let brick = crate::contract::bricks::BRICK as u32;
    if !(8..=512).contains(&chunk) || !chunk.is_multiple_of(brick) {
        return Err(Error::invalid(
            format!("--chunk {chunk}"),
            format!("must be 8..=512 voxels and a multiple of {brick} (the engine's brick edge)"),
        ));
    }
    Ok(chunk)
}

/// Parse `--chunks-of I/N`: this process's share, (I, N) with I < N.
pub fn parse_chunks_of(text: &str) -> crate::Result<(u32, u32)> {
    let what = format!("--chunks-of {text}");
    let expected = "expected I/N, two whole numbers with I < N (0/4, 1/4, 2/4 and 3/4 share an \
                    array among four processes)";
    let (i, n) = text
        .split_once('/')
        .ok_or_else(|| Error::invalid(&what, expected))?;
    let number = |t: &str| {
        t.trim()
            .parse::<u32>()
            .map_err(|_| Error::invalid(&what, expected))
    };
    let (i, n) = (number(i)?, number(n)?);
    if n == 0 {
        return Err(Error::invalid(&what, "N must be at least 1"));
    }
    if i >= n {
        return Err(Error::invalid(
            &what,
            format!(
                "I must be less than N (I counts from 0: 0/{n} .. {}/{n})",
                n - 1
            ),
        ));
    }
    Ok((i, n))
}

/// Refuse the outputs a Zarr array cannot come with: those made from the whole volume (never
/// held here) and the options of other formats.
fn check_other_outputs(args: &SolidArgs) -> crate::Result<()> {
    let whole = [
        ("--slices", args.slices.is_some()),
        ("--flipbook", args.flipbook.is_some()),
        ("--vti", args.vti.is_some()),
        ("--sheet", args.sheet.is_some()),
        ("--triples", args.triples.is_some()),
    ];
    if let Some((flag, _)) = whole.iter().find(|(_, given)| *given) {
        return Err(Error::invalid(
            format!("{flag} with a Zarr output"),
            "a Zarr array is written chunk by chunk and never held whole: write that output \
             with a command of its own",
        ));
    }
    let options = [
        ("--srgb", args.srgb),
        ("--mips", args.mips),
        ("--voxel-size", args.voxel_size != 1.0),
    ];
    if let Some((flag, _)) = options.iter().find(|(_, given)| *given) {
        return Err(Error::invalid(
            format!("{flag} with a Zarr output"),
            "belongs to other formats (KTX2, OpenVDB)",
        ));
    }
    Ok(())
}

/// A Zarr output's request: the box, its chunks, and which of them this process computes.
#[derive(Clone, Debug)]
pub struct ZarrJob<'a> {
    pub region: Box3,
    /// Chunk edge in voxels ([`check_chunk`]).
    pub chunk: u32,
    /// Keep complete chunks already there (`--resume`).
    pub resume: bool,
    /// (I, N) of `--chunks-of`: this process computes chunks k with k mod N = I.
    pub share: Option<(u32, u32)>,
    pub out: &'a Path,
    /// The array's attributes. Every process filling the array must give the same (their
    /// `zarr.json` must be identical): what defines the voxels, nothing of one process (not
    /// `--chunks-of`, the backend or `--max-group`).
    pub attributes: serde_json::Value,
}

/// What [`write_zarr`] did (`region --json` with a Zarr output).
#[derive(Clone, Debug, serde::Serialize)]
pub struct ZarrSummary {
    pub output: PathBuf,
    /// The half-open box, [lo, hi]: array element [0, 0, 0, c] is voxel lo.
    pub r#box: [[i32; 3]; 2],
    /// (Z, Y, X, C).
    pub shape: [u64; 4],
    pub chunk: u32,
    /// Chunks in the array.
    pub chunks: u64,
    /// `--chunks-of` as [I, N].
    pub chunks_of: Option<[u32; 2]>,
    /// This process's chunks, those it wrote and those it found complete (`--resume`).
    pub chunks_assigned: u64,
    pub chunks_written: u64,
    pub chunks_skipped: u64,
    /// Whether this process wrote `zarr.json` (false: it joined an array already there).
    pub created: bool,
    pub synthesis_seconds: f64,
}

/// Write this process's chunks of the array `job` describes: check the path and make or join
/// the array (nothing written when refused), then synthesize each chunk the share assigns,
/// skipping complete ones with `--resume`, and write it atomically, reporting to `report`
/// (stage, fraction). One chunk's voxels are held at a time.
pub fn write_zarr(
    solid: &mut Solid,
    job: &ZarrJob,
    report: &dyn Fn(&str, f32),
) -> crate::Result<ZarrSummary> {
    let start = Instant::now();
    let chunk = check_chunk(job.chunk)?;
    let (first, step) = job.share.unwrap_or((0, 1));
    if step == 0 || first >= step {
        return Err(Error::invalid(
            format!("--chunks-of {first}/{step}"),
            "I must be less than N",
        ));
    }
    solid.check_box_memory(&format!("--chunk {chunk}"), [chunk as u64; 3])?;
    let channels = solid.color_channels();
    let layout = Layout::new(job.region.size(), channels, chunk)?;
    let total = layout.chunk_count();
    let ours = || (first as u64..total).step_by(step as usize);
    let assigned = ours().count() as u64;
    if assigned == 0 {
        return Err(Error::invalid(
            format!("--chunks-of {first}/{step}"),
            format!("the array has {total} chunks, so share {first} would compute none; use N <= {total}"),
        ));
    }
    check_disk_space(job.out, &layout, ours(), assigned, job.resume)?;
    let may_join = job.resume || job.share.is_some();
    let metadata = zarr::metadata(&layout, &job.attributes);
    let opened = zarr::open(job.out, "-o", &metadata, may_join)?;
    // Nothing is overwritten: without --resume, this share's chunks must all be missing.
    if opened == Opened::Joined && !job.resume {
        if let Some(k) = ours().find(|&k| zarr::chunk_exists(job.out, layout.chunk_at(k))) {
            return Err(Error::invalid(
                format!("-o {}", job.out.display()),
                format!(
                    "already holds chunk {} of this share (nothing is overwritten): --resume \
                     keeps the chunks there and computes the others",
                    zarr::chunk_key(layout.chunk_at(k))
                ),
            ));
        }
    }
    let bytes = layout.chunk_bytes();
    let mut buffer = vec![0u8; bytes];
    let (mut written, mut skipped) = (0u64, 0u64);
    for (done, k) in ours().enumerate() {
        let at = layout.chunk_at(k);
        if job.resume && zarr::chunk_is_complete(job.out, at, bytes) {
            skipped += 1;
        } else {
            let (lo, size) = layout.chunk_extent(at);
            let lo = [0, 1, 2].map(|a| job.region.lo[a] + lo[a] as i32);
            let b = Box3::new(lo, [0, 1, 2].map(|a| lo[a] + size[a] as i32));
            synthesize_chunk(solid, b, chunk, channels, &mut buffer)?;
            zarr::write_chunk(job.out, at, &buffer)?;
            written += 1;
        }
        let done = done as u64 + 1;
        report(
            &format!("chunk {done}/{assigned} ({skipped} already there)"),
            done as f32 / assigned as f32,
        );
    }
    Ok(ZarrSummary {
        output: job.out.to_path_buf(),
        r#box: [job.region.lo, job.region.hi],
        shape: layout.shape(),
        chunk,
        chunks: total,
        chunks_of: job.share.map(|(i, n)| [i, n]),
        chunks_assigned: assigned,
        chunks_written: written,
        chunks_skipped: skipped,
        created: opened == Opened::Created,
        synthesis_seconds: start.elapsed().as_secs_f64(),
    })
}

/// Refuse a share of `chunks` (`count` of them) that cannot fit on the output's file system, before the array is
/// made or joined: each chunk file holds a whole chunk (the `bytes` codec stores no less), and
/// with `--resume` the chunks already complete need no room. (Processes sharing one array each
/// check their own share.)
fn check_disk_space(
    out: &Path,
    layout: &Layout,
    chunks: impl Iterator<Item = u64>,
    count: u64,
    resume: bool,
) -> crate::Result<()> {
    let Some(free) = crate::util::disk::free_bytes(out) else {
        return Ok(());
    };
    let bytes = layout.chunk_bytes() as u64;
    let needed = |count: u64| count.saturating_mul(bytes);
    if needed(count) <= free {
        return Ok(());
    }
    let missing = if resume && out.is_dir() {
        chunks
            .filter(|&k| !zarr::chunk_is_complete(out, layout.chunk_at(k), bytes as usize))
            .count() as u64
    } else {
        count
    };
    if needed(missing) > free {
        use crate::util::memory::human_bytes;
        return Err(Error::invalid(
            format!("-o {}", out.display()),
            format!(
                "the {missing} chunks to write need {} on disk, and {} is free there",
                human_bytes(needed(missing)),
                human_bytes(free)
            ),
        ));
    }
    Ok(())
}

/// The voxels of box `b` (at most a chunk: clipped at the volume's far edges) into `buffer`, a
/// whole chunk of edge `chunk` in C order of (z, y, x, c), zeros past the box.
fn synthesize_chunk(
    solid: &mut Solid,
    b: Box3,
    chunk: u32,
    channels: u32,
    buffer: &mut [u8],
) -> crate::Result<()> {
    let size = b.size();
    if size.iter().any(|&s| s != chunk) {
        buffer.fill(0);
    }
    let (c, ny) = (chunk as usize, size[1] as usize);
    let row = size[0] as usize * channels as usize;
    let chunk_row = c * channels as usize;
    solid.region_slabs(b, false, |slab| {
        let v = slab.volume;
        for z in 0..v.nz as usize {
            let zc = slab.z0 as usize + z;
            for y in 0..ny {
                let from = (z * ny + y) * row;
                let to = (zc * c + y) * chunk_row;
                buffer[to..to + row].copy_from_slice(&v.data[from..from + row]);
            }
        }
        Ok(())
    })
}

/// The array's attributes for `region` with `args`: what defines its voxels (shared by every
/// process filling it), `analysis` identified by a digest of its bytes (the same exemplar and
/// analysis settings however it was given: images, the cache or an .ssa file).
pub fn attributes(
    region: Box3,
    args: &SolidArgs,
    analysis: &crate::analysis::Analysis,
) -> serde_json::Value {
    let p = &args.solid;
    let digest = xxhash_rust::xxh3::xxh3_128(&crate::io::ssa::to_bytes(analysis));
    serde_json::json!({
        "solidsynth": {
            "version": env!("CARGO_PKG_VERSION"),
            "origin": region.lo,
            "box": [region.lo, region.hi],
            "element": "array[z, y, x, c] is channel c of voxel origin + (x, y, z) of the solid",
            "analysis_xxh3": format!("{digest:032x}"),
            "seed": p.seed,
            "jitter": p.jitter,
            "candidates": p.candidates,
            "passes": p.passes,
            "color": p.color,
            "coarse_cache": p.coarse_cache,
        }
    })
}

/// `region --json` with a Zarr output.
#[derive(serde::Serialize)]
struct RegionZarrSummary<'a> {
    #[serde(flatten)]
    zarr: &'a ZarrSummary,
    seed: u64,
    analysis_seconds: f64,
    peak_rss_bytes: Option<u64>,
    backend: String,
}

/// `region --box ... -o OUT.zarr`: every check that needs no analysis first (nothing written
/// when one fails), then the solid, then this process's chunks.
pub fn run(
    region: Box3,
    args: &SolidArgs,
    zarr_args: &ZarrArgs,
    quiet: bool,
) -> anyhow::Result<()> {
    let chunk = check_chunk(zarr_args.chunk.unwrap_or(DEFAULT_CHUNK))?;
    let share = zarr_args
        .chunks_of
        .as_deref()
        .map(parse_chunks_of)
        .transpose()?;
    check_other_outputs(args)?;
    let may_join = zarr_args.resume || share.is_some();
    zarr::check_target(&args.output, "-o", may_join)?;
    args.solid.synth_params().validate()?;
    let start = Instant::now();
    let (compute, analysis) = open_and_analyze(&args.solid.input, quiet || args.json)?;
    let analysis_s = start.elapsed().as_secs_f64();
    let mut solid = args.solid.solid(&analysis, &compute, args.profile, None)?;
    let job = ZarrJob {
        region,
        chunk,
        resume: zarr_args.resume,
        share,
        out: &args.output,
        attributes: attributes(region, args, &analysis),
    };
    // The synthesizer keeps what it reads of the analysis.
    drop(analysis);
    let bar = super::progress_bar(quiet || args.json);
    let report = |stage: &str, f: f32| bar.report(stage, f);
    let summary = write_zarr(&mut solid, &job, &report)?;
    bar.finish_and_clear();
    if args.json {
        print_summary(&RegionZarrSummary {
            zarr: &summary,
            seed: args.solid.seed,
            analysis_seconds: analysis_s,
            peak_rss_bytes: crate::util::memory::peak_rss_bytes(),
            backend: compute.describe(),
        });
    } else if !quiet {
        let [z, y, x, c] = summary.shape;
        let share = match summary.chunks_of {
            Some([i, n]) => format!(" (share {i}/{n} of {})", summary.chunks),
            None => String::new(),
        };
        eprintln!(
            "wrote {} of {} chunks{share} ({} already there) of the {x}x{y}x{z}x{c} array at {:?} \
             in {:.2} s (analysis {analysis_s:.2} s) -> {}",
            summary.chunks_written,
            summary.chunks_assigned,
            summary.chunks_skipped,
            region.lo,
            summary.synthesis_seconds,
            args.output.display()
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_of_is_i_of_n_with_i_below_n() {
        assert_eq!(parse_chunks_of("0/1").unwrap(), (0, 1));
        assert_eq!(parse_chunks_of("3/4").unwrap(), (3, 4));
        assert_eq!(parse_chunks_of(" 2 / 5 ").unwrap(), (2, 5));
        for (bad, needle) in [
            ("3/2", "less than N"),
            ("2/2", "less than N"),
            ("0/0", "at least 1"),
            ("x/2", "expected I/N"),
            ("2", "expected I/N"),
            ("-1/2", "expected I/N"),
            ("1/2/3", "expected I/N"),
        ] {
            let e = parse_chunks_of(bad).unwrap_err();
            let text = e.to_string();
            assert!(e.is_user_error(), "{bad}");
            assert!(text.contains(&format!("--chunks-of {bad}")), "{text}");
            assert!(text.contains(needle), "{bad}: {text}");
        }
    }

    #[test]
    fn chunks_are_8_to_512_voxels_in_whole_bricks() {
        for good in [8, 16, 128, 132, 512] {
            assert_eq!(check_chunk(good).unwrap(), good);
        }
        for bad in [0, 4, 6, 30, 516, 1024] {
            let e = check_chunk(bad).unwrap_err();
            assert!(e.to_string().contains(&format!("--chunk {bad}")), "{e}");
        }
    }
}
