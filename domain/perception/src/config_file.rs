//! Perception's configuration file (TOML): [`PerceptionConfig`] with every key optional.
//! `config/default.toml` documents the laser-scan keys.

use std::path::Path;

use crate::pipeline::PerceptionConfig;

/// The documented defaults of the laser-scan policy.
pub const DEFAULT_CONFIG: &str = include_str!("../config/default.toml");

pub use harvest_ipc::config_file::ConfigFileError;

/// What the file holds, in errors.
const WHAT: &str = "perception config";

/// Reads a configuration file. Values are range-checked when the pipeline is built.
pub fn read_config(path: &Path) -> Result<PerceptionConfig, ConfigFileError> {
    harvest_ipc::config_file::read_toml(path, WHAT)
}

/// Parses configuration text; `origin` names it in errors.
pub fn parse_config(text: &str, origin: &str) -> Result<PerceptionConfig, ConfigFileError> {
    harvest_ipc::config_file::parse_toml(text, origin, WHAT)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::depth_source::DepthSource;

    #[test]
    fn the_documented_defaults_are_the_code_defaults() {
        let config = parse_config(DEFAULT_CONFIG, "default.toml").expect("parse");
        assert_eq!(config, PerceptionConfig::default());
    }

    #[test]
    fn unknown_keys_are_named_with_the_file() {
        let bad = DEFAULT_CONFIG.replace("max_scans_per_frame", "max_scans");
        let message = parse_config(&bad, "bad.toml")
            .expect_err("unknown key")
            .to_string();
        assert!(
            message.contains("bad.toml") && message.contains("max_scans"),
            "{message}"
        );
        let config = parse_config("[laser]\nenabled = false\n", "off.toml").expect("parse");
        assert!(!config.laser.enabled);
        assert_eq!(config.min_detection_confidence, 0.3);
    }

    #[test]
    fn the_lidar_profile_selects_the_fused_depth_and_no_laser() {
        let text = include_str!("../config/lidar.toml");
        let config = parse_config(text, "lidar.toml").expect("parse");
        assert_eq!(config.depth_source, DepthSource::LidarFused);
        assert!(!config.laser.enabled);
        let bad = parse_config("depth_source = \"stereo\"\n", "bad.toml")
            .expect_err("unknown source")
            .to_string();
        assert!(bad.contains("bad.toml") && bad.contains("stereo"), "{bad}");
    }
}
