//! The analysis cache: analyses kept on disk, keyed by a 128-bit XXH3 hash of everything an
//! analysis depends on (the decoded pixels and masks, the border, the analysis parameters as
//! typed bytes, the `.ssa` format version and the algorithm revision). Each cached file holds
//! its key; a file that fails its checks (damaged, truncated, another key, an old format) is
//! analysed again and replaced, with a warning, never used. Writes are atomic (a temporary file
//! renamed into place), so processes analysing the same image at once leave one whole file.

use crate::analysis::{Analysis, AnalysisInput, AnalysisParams, ALGORITHM_REVISION};
use crate::error::{Error, Result};
use crate::io::{atomic, ssa};
use std::path::{Path, PathBuf};

/// The magic of a cached analysis file: then the 16-byte key, then the `.ssa` bytes.
const MAGIC: &[u8; 8] = b"SSACACHE";

/// A directory of cached analyses.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AnalysisCache {
    dir: PathBuf,
}

/// What a look-up found.
#[derive(Debug)]
pub enum Cached {
    /// A valid analysis of this input.
    Hit(Analysis),
    /// Nothing cached for this input.
    Miss,
    /// A file under this input's name that failed its checks (to be replaced), and why.
    Invalid(String),
}

impl AnalysisCache {
    /// A cache in `dir` (created when the first analysis is stored).
    pub fn at(dir: impl Into<PathBuf>) -> AnalysisCache {
        AnalysisCache { dir: dir.into() }
    }

    /// The user's cache: `$SOLIDSYNTH_CACHE_DIR`, else `$XDG_CACHE_HOME/solidsynth`, else
    /// `~/.cache/solidsynth`; None where none of them is set.
    pub fn user_default() -> Option<AnalysisCache> {
        if let Some(d) = std::env::var_os("SOLIDSYNTH_CACHE_DIR") {
            return Some(AnalysisCache::at(d));
        }
        let base = std::env::var_os("XDG_CACHE_HOME")
            .map(PathBuf::from)
            .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
        Some(AnalysisCache::at(base.join("solidsynth")))
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The file of the analysis with `key`.
    pub fn path(&self, key: u128) -> PathBuf {
        self.dir.join(format!("{key:032x}.ssa"))
    }

    /// The cached analysis of `key`, checked.
    pub fn load(&self, key: u128) -> Cached {
        let path = self.path(key);
        let bytes = match std::fs::read(&path) {
            Ok(b) => b,
            // (No file, or no directory to hold one: the store says why.)
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::NotFound | std::io::ErrorKind::NotADirectory
                ) =>
            {
                return Cached::Miss
            }
            Err(e) => {
                return Cached::Invalid(format!("unreadable: {}", crate::error::io_problem(&e)))
            }
        };
        match parse(&bytes, key) {
            Ok(a) => Cached::Hit(a),
            Err(problem) => Cached::Invalid(problem),
        }
    }

    /// Store `analysis` under `key` (atomically: a temporary file renamed into place).
    pub fn store(&self, key: u128, analysis: &Analysis) -> Result<()> {
        if self.dir.exists() && !self.dir.is_dir() {
            return Err(Error::invalid(
                self.dir.display().to_string(),
                "is not a directory",
            ));
        }
        std::fs::create_dir_all(&self.dir).map_err(|e| Error::io(&self.dir, e))?;
        let mut bytes = Vec::new();
        bytes.extend_from_slice(MAGIC);
        bytes.extend_from_slice(&key.to_le_bytes());
        bytes.extend_from_slice(&ssa::to_bytes(analysis));
        atomic::write_file(&self.path(key), &bytes)
    }

    /// The analysis of `key`: the cached one when it is valid, else `analyze()`'s, stored
    /// (replacing an invalid file, with a warning). A cache that cannot be written costs a
    /// warning, not the analysis.
    pub fn get_or_analyze(
        &self,
        key: u128,
        analyze: impl FnOnce() -> Result<Analysis>,
    ) -> Result<Analysis> {
        self.get_or_analyze_warning(key, analyze, &|_| {})
    }

    /// [`Self::get_or_analyze`], its warnings also handed to `warn` (they are logged either
    /// way): for a caller whose users see no log (the Python package).
    pub fn get_or_analyze_warning(
        &self,
        key: u128,
        analyze: impl FnOnce() -> Result<Analysis>,
        warn: &dyn Fn(&str),
    ) -> Result<Analysis> {
        let warning = |text: String| {
            tracing::warn!("{text}");
            warn(&text);
        };
        match self.load(key) {
            Cached::Hit(a) => {
                tracing::info!("analysis from cache {}", self.path(key).display());
                return Ok(a);
            }
            Cached::Invalid(problem) => warning(format!(
                "cached analysis {} ignored ({problem}); analysing again",
                self.path(key).display()
            )),
            Cached::Miss => {}
        }
        let a = analyze()?;
        if let Err(e) = self.store(key, &a) {
            warning(format!("could not cache the analysis: {}", e.report()));
        }
        Ok(a)
    }
}

fn parse(bytes: &[u8], key: u128) -> std::result::Result<Analysis, String> {
    let header = MAGIC.len() + 16;
    if bytes.len() < header || &bytes[..MAGIC.len()] != MAGIC {
        return Err("not a cached analysis (wrong magic or too short)".into());
    }
    let stored = u128::from_le_bytes(bytes[MAGIC.len()..header].try_into().unwrap());
    if stored != key {
        return Err(format!(
            "it holds the analysis of another input ({stored:032x})"
        ));
    }
    ssa::from_bytes(&bytes[header..])
}

/// The cache key of an analysis input and its parameters: XXH3-128 over typed bytes, each
/// field and image length-prefixed (no two inputs share a byte stream).
pub fn cache_key(input: &AnalysisInput, params: &AnalysisParams) -> u128 {
    fn words(h: &mut xxhash_rust::xxh3::Xxh3, ws: &[u32]) {
        for w in ws {
            h.update(&w.to_le_bytes());
        }
    }
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    words(
        &mut h,
        &[
            ssa::FORMAT_VERSION,
            ALGORITHM_REVISION,
            input.border.code(),
            params.strips_per_axis,
            params.crossbar_keep,
            params.max_3d,
            params.max_filter_rounds,
            params.feature_weight.to_bits(),
            params.balance_rounds,
            params.balance_strength.to_bits(),
        ],
    );
    words(&mut h, &params.pca_dims);
    words(&mut h, &params.k2d);
    words(
        &mut h,
        &[input.exemplars.len() as u32, input.masks.len() as u32],
    );
    for img in input.exemplars.iter().chain(&input.masks) {
        words(&mut h, &[img.width, img.height, img.channels]);
        h.update(&(img.pixels.len() as u64).to_le_bytes());
        h.update(&img.pixels);
    }
    h.digest128()
}
