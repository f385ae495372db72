//! `perception/apples` -> `/camera/annotations` (over `/camera/image`, in the shown image's
//! pixels) and `/apples/detected` (spheres in the robot frame).
//!
//! Each apple: a circle inscribed in its box (outline coloured by the depth source: yellow ToF,
//! cyan LiDAR-fused, magenta laser line) and a label `#<id> <depth source> <confidence>` at the
//! box's top-left corner. Annotations carry the camera frame's capture time, so Foxglove pairs
//! them with the image they were found in.

use crate::camera::ImageSettings;
use crate::color::{self, Rgba};
use crate::frames;
use crate::geometry::{IDENTITY, pose, vector};
use crate::stamps::TimeBase;
use foxglove::messages::{
    CircleAnnotation, Duration, ImageAnnotations, KeyValuePair, Point2, SceneEntity,
    SceneEntityDeletion, SceneUpdate, SpherePrimitive, TextAnnotation, scene_entity_deletion,
};
use harvest_ipc::WireCode;
use harvest_ipc::payloads::{AppleDetection, AppleDetections, DepthSourceCode};

/// How long a detected-apple sphere stays without a newer detection set, s.
pub const DETECTED_LIFETIME_S: f64 = 1.0;

/// Short name of a depth source code.
pub fn depth_source_name(code: WireCode<DepthSourceCode>) -> &'static str {
    match code.get() {
        Ok(DepthSourceCode::Tof) => "ToF",
        Ok(DepthSourceCode::LidarFused) => "LiDAR",
        Ok(DepthSourceCode::LaserLine) => "laser",
        Err(_) => "unknown",
    }
}

/// The outline colour of a depth source.
pub fn depth_source_color(code: WireCode<DepthSourceCode>) -> Rgba {
    match code.get() {
        Ok(DepthSourceCode::Tof) | Err(_) => color::YELLOW,
        Ok(DepthSourceCode::LidarFused) => color::CYAN,
        Ok(DepthSourceCode::LaserLine) => color::MAGENTA,
    }
}

/// Centre and diameter of the circle drawn for `apple`, in the shown image's pixels.
pub fn circle_px(apple: &AppleDetection, settings: &ImageSettings) -> ([f64; 2], f64) {
    let [x, y, width, height] = apple.box_px.map(f64::from);
    let centre = [
        settings.to_shown_px(x + width / 2.0),
        settings.to_shown_px(y + height / 2.0),
    ];
    (centre, settings.to_shown_px((width + height) / 2.0))
}

fn key_value(key: &str, value: String) -> KeyValuePair {
    KeyValuePair {
        key: key.to_owned(),
        value,
    }
}

/// The image overlay of one detection set.
pub fn annotations(
    detections: &AppleDetections,
    settings: &ImageSettings,
    time: &TimeBase,
) -> ImageAnnotations {
    let timestamp = time.timestamp(detections.source_capture_ns);
    let apples = detections.apples.as_slice();
    let circles = apples
        .iter()
        .map(|apple| {
            let ([x, y], diameter) = circle_px(apple, settings);
            CircleAnnotation {
                timestamp: Some(timestamp),
                position: Some(Point2 { x, y }),
                diameter,
                thickness: 2.0,
                fill_color: Some(color::WHITE.with_alpha(0.0).into()),
                outline_color: Some(depth_source_color(apple.depth_source).into()),
                metadata: vec![key_value("apple_id", apple.apple_id.to_string())],
            }
        })
        .collect();
    let texts = apples
        .iter()
        .map(|apple| {
            let [x, y, _, _] = apple.box_px.map(f64::from);
            TextAnnotation {
                timestamp: Some(timestamp),
                position: Some(Point2 {
                    x: settings.to_shown_px(x),
                    y: settings.to_shown_px(y),
                }),
                text: format!(
                    "#{} {} {:.2}",
                    apple.apple_id,
                    depth_source_name(apple.depth_source),
                    apple.confidence
                ),
                font_size: 14.0,
                text_color: Some(color::WHITE.into()),
                background_color: Some(Rgba(0.0, 0.0, 0.0, 0.5).into()),
                metadata: vec![key_value("apple_id", apple.apple_id.to_string())],
            }
        })
        .collect();
    ImageAnnotations {
        timestamp: Some(timestamp),
        circles,
        points: Vec::new(),
        texts,
        metadata: vec![
            key_value("source_frame_seq", detections.source_frame_seq.to_string()),
            key_value("processing_ns", detections.processing_ns.to_string()),
        ],
    }
}

/// The detection set as spheres in the robot frame, replacing the previous set.
pub fn detected_apples(detections: &AppleDetections, time: &TimeBase) -> SceneUpdate {
    let timestamp = time.timestamp(detections.source_capture_ns);
    let entities = detections
        .apples
        .as_slice()
        .iter()
        .filter(|apple| apple.position_in_robot_m.iter().all(|v| v.is_finite()))
        .map(|apple| {
            let diameter = 2.0 * apple.radius_m.max(0.005);
            SceneEntity {
                timestamp: Some(timestamp),
                frame_id: frames::ROBOT.to_owned(),
                id: format!("detected/{}", apple.apple_id),
                lifetime: Some(Duration::saturating_from_secs_f64(DETECTED_LIFETIME_S)),
                frame_locked: false,
                metadata: vec![
                    key_value("apple_id", apple.apple_id.to_string()),
                    key_value(
                        "depth_source",
                        depth_source_name(apple.depth_source).to_owned(),
                    ),
                    key_value("confidence", format!("{:.3}", apple.confidence)),
                ],
                spheres: vec![SpherePrimitive {
                    pose: Some(pose(apple.position_in_robot_m, IDENTITY)),
                    size: Some(vector([diameter; 3])),
                    color: Some(
                        depth_source_color(apple.depth_source)
                            .with_alpha(0.5)
                            .into(),
                    ),
                }],
                ..SceneEntity::default()
            }
        })
        .collect();
    SceneUpdate {
        deletions: vec![SceneEntityDeletion {
            timestamp: Some(timestamp),
            r#type: scene_entity_deletion::Type::All as i32,
            id: String::new(),
        }],
        entities,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_ipc::payloads::LocalizationMethod;

    fn detections() -> AppleDetections {
        let mut set = AppleDetections {
            source_capture_ns: 5_000_000_000,
            source_frame_seq: 12,
            ..AppleDetections::default()
        };
        set.apples
            .push(AppleDetection {
                apple_id: 3,
                method: LocalizationMethod::SphereFit.into(),
                depth_source: DepthSourceCode::Tof.into(),
                position_in_robot_m: [1.4, 0.1, 0.6],
                radius_m: 0.04,
                confidence: 0.9,
                box_px: [100, 200, 60, 40],
                ..AppleDetection::default()
            })
            .expect("room");
        set.apples
            .push(AppleDetection {
                apple_id: 4,
                depth_source: DepthSourceCode::LaserLine.into(),
                position_in_robot_m: [f64::NAN; 3],
                box_px: [0, 0, 10, 10],
                ..AppleDetection::default()
            })
            .expect("room");
        set
    }

    #[test]
    fn annotations_sit_on_the_shown_image_and_carry_the_frame_time() {
        let overlay = annotations(&detections(), &ImageSettings::VIEWING, &TimeBase::MONOTONIC);
        assert_eq!(overlay.circles.len(), 2);
        let circle = &overlay.circles[0];
        let centre = circle.position.expect("position");
        assert_eq!((centre.x, centre.y), (65.0, 110.0));
        assert_eq!(circle.diameter, 25.0);
        assert_eq!(overlay.texts[0].text, "#3 ToF 0.90");
        assert_eq!(overlay.texts[1].text, "#4 laser 0.00");
        assert_eq!(overlay.timestamp.expect("stamp").sec(), 5);
        assert_eq!(
            circle.outline_color,
            Some(color::YELLOW.into()),
            "ToF outline"
        );
    }

    #[test]
    fn spheres_replace_the_previous_set_and_skip_unknown_positions() {
        let update = detected_apples(&detections(), &TimeBase::MONOTONIC);
        assert_eq!(update.deletions.len(), 1);
        assert_eq!(update.entities.len(), 1);
        let sphere = &update.entities[0].spheres[0];
        assert_eq!(sphere.size.expect("size").x, 0.08);
        assert_eq!(update.entities[0].frame_id, "robot");
    }
}
