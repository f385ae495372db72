//! The stack's camera model ([`CameraIntrinsics`]: pinhole with Brown-Conrady `[k1, k2, p1,
//! p2, k3]`) and `sensor_msgs/CameraInfo` (`plumb_bob` holds the same five coefficients in the
//! same order).

use crate::error::FieldError;
use harvest_ipc::camera_model::CameraIntrinsics;
use harvest_ros2::msgs::sensor_msgs::CameraInfo;
use harvest_ros2::msgs::std_msgs::Header;

/// The camera model as `CameraInfo` (no rectification: `r` is the identity, `p` the
/// undistorted pinhole).
pub fn camera_info(intrinsics: &CameraIntrinsics, header: Header) -> CameraInfo {
    let CameraIntrinsics {
        width_px,
        height_px,
        fx_px,
        fy_px,
        cx_px,
        cy_px,
        distortion,
    } = *intrinsics;
    CameraInfo {
        header,
        height: height_px,
        width: width_px,
        distortion_model: "plumb_bob".to_owned(),
        d: distortion.to_vec(),
        k: [fx_px, 0.0, cx_px, 0.0, fy_px, cy_px, 0.0, 0.0, 1.0],
        r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: [
            fx_px, 0.0, cx_px, 0.0, 0.0, fy_px, cy_px, 0.0, 0.0, 0.0, 1.0, 0.0,
        ],
        ..CameraInfo::default()
    }
}

/// The stack's camera model from `CameraInfo`: `k` for the pinhole; `plumb_bob` (or
/// `rational_polynomial` whose k4-k6 are zero) for the distortion; no distortion when `d` is
/// empty. Binning, a region of interest, skew and other models are refused.
pub fn intrinsics(info: &CameraInfo) -> Result<CameraIntrinsics, FieldError> {
    let k = info.k;
    if k[1] != 0.0 {
        return Err(FieldError::new(
            "k",
            format!("skew k[1] = {} (the stack's camera model has none)", k[1]),
        ));
    }
    let coefficients: &[f64] = &info.d;
    let distortion = match (info.distortion_model.as_str(), coefficients.len()) {
        (_, 0) => [0.0; 5],
        ("plumb_bob", 5) => [
            coefficients[0],
            coefficients[1],
            coefficients[2],
            coefficients[3],
            coefficients[4],
        ],
        ("rational_polynomial", 8) if coefficients[5..].iter().all(|c| *c == 0.0) => [
            coefficients[0],
            coefficients[1],
            coefficients[2],
            coefficients[3],
            coefficients[4],
        ],
        (model, len) => {
            return Err(FieldError::new(
                "distortion_model",
                format!(
                    "{model:?} with {len} coefficient(s): the stack takes plumb_bob (k1, k2, t1, t2, k3), or rational_polynomial whose k4-k6 are 0"
                ),
            ));
        }
    };
    if info.binning_x > 1 || info.binning_y > 1 {
        return Err(FieldError::new(
            "binning_x",
            format!(
                "binning {} x {}: rescale the calibration to the image first",
                info.binning_x, info.binning_y
            ),
        ));
    }
    let roi = info.roi;
    if (roi.width != 0 && roi.width != info.width) || (roi.height != 0 && roi.height != info.height)
    {
        return Err(FieldError::new(
            "roi",
            format!(
                "region of interest {} x {} at ({}, {}) of a {} x {} image: not supported",
                roi.width, roi.height, roi.x_offset, roi.y_offset, info.width, info.height
            ),
        ));
    }
    let intrinsics = CameraIntrinsics {
        width_px: info.width,
        height_px: info.height,
        fx_px: k[0],
        fy_px: k[4],
        cx_px: k[2],
        cy_px: k[5],
        distortion,
    };
    match intrinsics.problem() {
        Some(problem) => Err(FieldError::new("k", problem)),
        None => Ok(intrinsics),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_camera_model_survives_camera_info() {
        for intrinsics in [
            CameraIntrinsics::tl460_rgb(),
            CameraIntrinsics::tl460_depth(),
        ] {
            let info = camera_info(&intrinsics, Header::default());
            assert_eq!(super::intrinsics(&info).unwrap(), intrinsics);
        }
    }

    #[test]
    fn unsupported_models_name_their_field() {
        let mut info = camera_info(&CameraIntrinsics::tl460_rgb(), Header::default());
        info.distortion_model = "equidistant".into();
        info.d = vec![0.1, 0.0, 0.0, 0.0];
        assert_eq!(intrinsics(&info).unwrap_err().field, "distortion_model");
        let mut info = camera_info(&CameraIntrinsics::tl460_rgb(), Header::default());
        info.k[0] = 0.0;
        assert_eq!(intrinsics(&info).unwrap_err().field, "k");
        info.k[0] = 100.0;
        info.binning_x = 2;
        assert_eq!(intrinsics(&info).unwrap_err().field, "binning_x");
    }
}
