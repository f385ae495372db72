//! The one place a detector is chosen: [`DetectorConfig`] (the `[detector]` table of
//! perception's config, `kind = "color_segmentation"` or `kind = "onnx"`) and [`make_detector`].

use serde::{Deserialize, Serialize};

use super::Detector;
use super::color_segmentation::{ColorSegmentation, ColorSegmentationConfig};
use super::onnx::OnnxDetectorConfig;
#[cfg(not(feature = "onnx"))]
use super::onnx::OnnxDetectorError;
use crate::pipeline::PerceptionSetupError;

/// Which detector perception runs, with its parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum DetectorConfig {
    /// The classical colour segmentation (the default).
    ColorSegmentation(ColorSegmentationConfig),
    /// A YOLO detect or segment model exported to ONNX.
    Onnx(OnnxDetectorConfig),
}

impl Default for DetectorConfig {
    fn default() -> Self {
        Self::ColorSegmentation(ColorSegmentationConfig::default())
    }
}

impl DetectorConfig {
    /// `color_segmentation` or `onnx`.
    pub fn kind_name(&self) -> &'static str {
        match self {
            Self::ColorSegmentation(_) => "color_segmentation",
            Self::Onnx(_) => "onnx",
        }
    }
}

/// The detector kinds, as the command line names them (`--detector`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DetectorKind {
    ColorSegmentation,
    Onnx,
}

impl std::str::FromStr for DetectorKind {
    type Err = String;

    /// The config-file spelling (`color_segmentation`) or the command line's
    /// (`color-segmentation`).
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        match text {
            "color_segmentation" | "color-segmentation" => Ok(Self::ColorSegmentation),
            "onnx" => Ok(Self::Onnx),
            other => Err(format!(
                "unknown detector `{other}` (expected color-segmentation or onnx)"
            )),
        }
    }
}

impl DetectorConfig {
    /// Applies the command line's `--detector KIND` and `--model FILE` to the configured
    /// detector: a kind other than the configured one starts from its defaults; `--model` sets
    /// the ONNX model (the configured detector must then be, or be made, `onnx`).
    pub fn override_with(
        &mut self,
        kind: Option<DetectorKind>,
        model: Option<&std::path::Path>,
    ) -> Result<(), String> {
        match (kind, &mut *self) {
            (Some(DetectorKind::ColorSegmentation), Self::ColorSegmentation(_)) | (None, _) => {}
            (Some(DetectorKind::ColorSegmentation), _) => *self = Self::default(),
            (Some(DetectorKind::Onnx), Self::Onnx(_)) => {}
            (Some(DetectorKind::Onnx), _) => {
                let model = model.ok_or(
                    "--detector onnx needs --model FILE (or [detector] model in the config)",
                )?;
                *self = Self::Onnx(OnnxDetectorConfig::with_model(model.to_path_buf()));
            }
        }
        match (self, model) {
            (Self::Onnx(onnx), Some(model)) => onnx.model = model.to_path_buf(),
            (Self::ColorSegmentation(_), Some(_)) => {
                return Err(
                    "--model applies to the onnx detector (add --detector onnx)".to_string()
                );
            }
            (_, None) => {}
        }
        Ok(())
    }
}

/// Builds the configured detector. An ONNX model is loaded and its layout checked here, so a
/// process refuses a bad model at start.
pub fn make_detector(
    config: &DetectorConfig,
) -> Result<Box<dyn Detector + Send>, PerceptionSetupError> {
    match config {
        DetectorConfig::ColorSegmentation(config) => Ok(Box::new(ColorSegmentation::new(*config)?)),
        DetectorConfig::Onnx(config) => make_onnx(config),
    }
}

#[cfg(feature = "onnx")]
fn make_onnx(
    config: &OnnxDetectorConfig,
) -> Result<Box<dyn Detector + Send>, PerceptionSetupError> {
    Ok(Box::new(super::onnx::OnnxDetector::new(config)?))
}

#[cfg(not(feature = "onnx"))]
fn make_onnx(
    config: &OnnxDetectorConfig,
) -> Result<Box<dyn Detector + Send>, PerceptionSetupError> {
    config.validate().map_err(OnnxDetectorError::from)?;
    Err(OnnxDetectorError::NotBuilt.into())
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::config_file::parse_config;

    #[test]
    fn the_detector_table_selects_the_kind_and_refuses_unknown_keys() {
        let config = parse_config("", "empty.toml").expect("parse");
        assert_eq!(config.detector, DetectorConfig::default());
        let text = "[detector]\nkind = \"onnx\"\nmodel = \"apples.onnx\"\nclasses = [0, 2]\n\
                    providers = [\"tensorrt\", \"cuda\", \"cpu\"]\nrequire_gpu = true\n";
        let config = parse_config(text, "onnx.toml").expect("parse");
        let DetectorConfig::Onnx(onnx) = &config.detector else {
            panic!("{:?}", config.detector);
        };
        assert_eq!(onnx.model, Path::new("apples.onnx"));
        assert_eq!(onnx.classes, [0, 2]);
        assert_eq!(onnx.input_size, 640);
        assert!(onnx.require_gpu && onnx.validate().is_ok());
        let colour = parse_config(
            "[detector]\nkind = \"color_segmentation\"\ndownscale = 2\n",
            "colour.toml",
        )
        .expect("parse");
        assert!(
            matches!(colour.detector, DetectorConfig::ColorSegmentation(c) if c.downscale == 2)
        );
        for (bad, named) in [
            (
                "[detector]\nkind = \"onnx\"\nmodel = \"a.onnx\"\nscore = 0.3\n",
                "score",
            ),
            ("[detector]\nkind = \"onnx\"\n", "model"),
            ("[detector]\nkind = \"yolo\"\n", "yolo"),
            (
                "[detector]\nkind = \"onnx\"\nmodel = \"a.onnx\"\nproviders = [\"npu\"]\n",
                "npu",
            ),
        ] {
            let message = parse_config(bad, "bad.toml").expect_err(bad).to_string();
            assert!(
                message.contains("bad.toml") && message.contains(named),
                "{message}"
            );
        }
    }

    #[test]
    fn the_command_line_overrides_kind_and_model() {
        let mut config = DetectorConfig::default();
        config.override_with(None, None).expect("nothing");
        assert_eq!(config, DetectorConfig::default());
        assert!(
            config
                .override_with(Some(DetectorKind::Onnx), None)
                .is_err()
        );
        assert!(
            config
                .override_with(None, Some(Path::new("m.onnx")))
                .is_err()
        );
        config
            .override_with(Some(DetectorKind::Onnx), Some(Path::new("m.onnx")))
            .expect("onnx");
        assert_eq!(
            config,
            DetectorConfig::Onnx(OnnxDetectorConfig::with_model("m.onnx".into()))
        );
        config
            .override_with(None, Some(Path::new("n.onnx")))
            .expect("model only");
        assert!(matches!(&config, DetectorConfig::Onnx(c) if c.model == Path::new("n.onnx")));
        config
            .override_with(Some(DetectorKind::ColorSegmentation), None)
            .expect("back");
        assert_eq!(config, DetectorConfig::default());
        assert_eq!(
            "color-segmentation".parse(),
            Ok(DetectorKind::ColorSegmentation)
        );
        assert!("yolo".parse::<DetectorKind>().is_err());
    }

    #[test]
    fn an_onnx_detector_that_cannot_start_is_a_setup_error() {
        let mut onnx = OnnxDetectorConfig::with_model("/nonexistent/apples.onnx".into());
        onnx.input_size = 100;
        let error = make_detector(&DetectorConfig::Onnx(onnx))
            .err()
            .expect("input size");
        assert!(error.to_string().contains("input_size = 100"), "{error}");
    }
}
