//! The exemplar side of a solid: one image or three, how they lie in the three planes, the
//! feature channel's masks, whether they tile, and the usage balancing: assembled into the
//! analysis input exactly as the command line does, so the same settings give the same solid
//! through either.

use crate::analysis::frame::{self, InputFrame};
use crate::analysis::{balance, AnalysisInput, AnalysisParams, DEFAULT_FEATURE_WEIGHT};
use crate::error::{Error, Result};
use crate::exemplar::{self, Border, Image};

/// Where the feature channel's masks come from (`--feature-mask`).
#[derive(Clone, Debug, Default, PartialEq)]
pub enum FeatureMasks {
    /// Each exemplar's luminance split in two by Otsu's threshold (`auto`, the default).
    #[default]
    Auto,
    /// Each exemplar's strong edges (`edges`: cells, mortar grids, cracks).
    Edges,
    /// No feature channel: the paper's plain colour search (`none`).
    None,
    /// Mask images (white inside), one per exemplar, each the size of its exemplar.
    Images(Vec<Image>),
}

/// The exemplars and how they are analysed. The defaults are the command line's.
#[derive(Clone, Debug)]
pub struct ExemplarInput {
    /// One image for all three planes, or three (x, y, z); empty: the built-in exemplar.
    pub images: Vec<Image>,
    /// Names for messages (`exemplar PATH`, `--ey PATH`), one per image.
    pub names: Vec<String>,
    /// How the images lie in the three planes (`--frame`); None: the paper's where it fits.
    pub frame: Option<InputFrame>,
    pub feature_masks: FeatureMasks,
    /// Weight of the feature channel relative to one colour channel (`--feature-weight`).
    pub feature_weight: f32,
    /// The images tile (`--periodic`); else their edges are mirrored. The built-in exemplar
    /// tiles.
    pub periodic: bool,
    /// Usage-balancing rounds and strength (`--balance-rounds`, `--balance-strength`).
    pub balance_rounds: u32,
    pub balance_strength: f32,
}

impl Default for ExemplarInput {
    fn default() -> Self {
        ExemplarInput {
            images: Vec::new(),
            names: Vec::new(),
            frame: None,
            feature_masks: FeatureMasks::Auto,
            feature_weight: DEFAULT_FEATURE_WEIGHT,
            periodic: false,
            balance_rounds: balance::DEFAULT_ROUNDS,
            balance_strength: 1.0,
        }
    }
}

impl ExemplarInput {
    /// The analysis input and parameters: images loaded, masks made or checked, and all of them
    /// in the crate's frame (with the paper's frame one image becomes three exemplars, Ey
    /// transposed).
    pub fn analysis_input(&self) -> Result<(AnalysisInput, AnalysisParams)> {
        let mut exemplars = self.images.clone();
        let mut names = self.names.clone();
        names.resize_with(exemplars.len(), Default::default);
        for (i, name) in names.iter_mut().enumerate() {
            if name.is_empty() {
                *name = ["exemplar", "--ey", "--ez"][i.min(2)].to_string();
            }
        }
        let mut border = if self.periodic {
            Border::Wrap
        } else {
            Border::Mirror
        };
        match exemplars.len() {
            0 => {
                exemplars.push(exemplar::default_exemplar());
                names.push("built-in exemplar".into());
                border = Border::Wrap;
            }
            1 | 3 => {}
            n => {
                return Err(Error::invalid(
                    "exemplars",
                    format!("{n} images: give one (all planes) or three (x, y, z)"),
                ))
            }
        }
        // Checked before anything is computed from them (masks, frame).
        for (img, name) in exemplars.iter().zip(&names) {
            exemplar::check_exemplar_size(img, name)?;
        }
        for (img, name) in exemplars.iter().zip(&names).skip(1) {
            if (img.width, img.height) != (exemplars[0].width, exemplars[0].height) {
                return Err(Error::invalid(
                    name,
                    format!(
                        "is {}x{} but the x exemplar is {}x{}; Ex, Ey and Ez must have the same size",
                        img.width, img.height, exemplars[0].width, exemplars[0].height
                    ),
                ));
            }
        }
        if self.feature_masks == FeatureMasks::None && self.feature_weight != DEFAULT_FEATURE_WEIGHT
        {
            return Err(Error::invalid(
                "--feature-weight",
                "has no effect with --feature-mask none (there is no feature channel)",
            ));
        }
        let masks = match &self.feature_masks {
            FeatureMasks::Images(masks) => {
                if masks.len() != exemplars.len() {
                    return Err(Error::invalid(
                        "feature masks",
                        if exemplars.len() == 3 {
                            "give --feature-mask, --ey-feature-mask and --ez-feature-mask images together"
                        } else {
                            "give --feature-mask only (one exemplar)"
                        },
                    ));
                }
                masks.clone()
            }
            FeatureMasks::Auto => exemplar::feature::auto_masks(&exemplars),
            FeatureMasks::Edges => exemplar::feature::edge_masks(&exemplars, border),
            FeatureMasks::None => Vec::new(),
        };
        let frame = frame::resolve_frame(&exemplars, self.frame)?;
        if self.frame.is_none() && frame == InputFrame::Cyclic {
            tracing::info!(
                "non-square exemplar: --frame cyclic (the paper's frame transposes the y exemplar)"
            );
        }
        if frame == InputFrame::Paper {
            if names.len() == 1 {
                names = vec![names[0].clone(), names[0].clone(), names[0].clone()];
            }
            names[1] = format!("{} (transposed: --frame paper)", names[1]);
        }
        let exemplars = frame::to_crate_frame(exemplars, frame);
        let masks = if masks.is_empty() {
            masks
        } else {
            frame::to_crate_frame(masks, frame)
        };
        let params = AnalysisParams {
            feature_weight: self.feature_weight,
            balance_rounds: self.balance_rounds,
            balance_strength: self.balance_strength,
            ..Default::default()
        };
        params.validate()?;
        Ok((
            AnalysisInput {
                exemplars,
                masks,
                border,
                names,
            },
            params,
        ))
    }

    /// Whether any analysis setting differs from the defaults (an `.ssa` file holds its own).
    pub fn analysis_settings_given(&self) -> bool {
        self.frame.is_some()
            || self.periodic
            || self.feature_masks != FeatureMasks::Auto
            || self.feature_weight != DEFAULT_FEATURE_WEIGHT
            || self.balance_rounds != balance::DEFAULT_ROUNDS
            || self.balance_strength != 1.0
    }
}
