//! The shipped Foxglove layout (`docs/foxglove/harvest-layout.json`) names only topics the
//! mapping publishes, `/vacuum` fields its schema declares and joints the arms report: a renamed
//! topic or field fails here instead of leaving an empty panel.

use foxglove::Encode;
use harvest_foxglove_mapping::arm_frames::JOINT_NAMES;
use harvest_foxglove_mapping::topics;
use harvest_foxglove_mapping::vacuum::VacuumView;
use prost::Message as _;
use prost_types::FileDescriptorSet;
use serde_json::Value;
use std::path::Path;

fn layout() -> Value {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/foxglove/harvest-layout.json");
    let text = std::fs::read_to_string(&path).expect("layout file");
    serde_json::from_str(&text).expect("layout JSON")
}

/// Every topic the layout's panels refer to, and every message path of its plots.
fn references(layout: &Value) -> (Vec<String>, Vec<String>) {
    let mut topics = Vec::new();
    let mut paths = Vec::new();
    for (panel, config) in layout["configById"].as_object().expect("configById") {
        if let Some(image) = config["imageMode"].as_object() {
            for key in ["imageTopic", "calibrationTopic"] {
                if let Some(topic) = image.get(key).and_then(Value::as_str) {
                    topics.push(topic.to_owned());
                }
            }
            if let Some(annotations) = image.get("annotations").and_then(Value::as_object) {
                topics.extend(annotations.keys().cloned());
            }
        }
        if let Some(scene_topics) = config["topics"].as_object() {
            topics.extend(scene_topics.keys().cloned());
        }
        if let Some(topic) = config["topicToRender"].as_str() {
            topics.push(topic.to_owned());
        }
        if let Some(plot_paths) = config["paths"].as_array() {
            for path in plot_paths {
                let value = path["value"].as_str().expect("plot path value");
                paths.push(value.to_owned());
            }
        }
        assert!(
            layout["layout"]
                .to_string()
                .contains(&format!("\"{panel}\"")),
            "panel {panel} is configured but not placed in the layout"
        );
    }
    (topics, paths)
}

#[test]
fn the_layout_refers_to_mapped_topics_and_fields() {
    let layout = layout();
    let mapped: Vec<&str> = topics::all().iter().map(|topic| topic.name).collect();
    let (panel_topics, plot_paths) = references(&layout);
    assert!(panel_topics.contains(&"/camera/image".to_owned()));
    assert!(panel_topics.contains(&"/camera/annotations".to_owned()));
    assert!(panel_topics.contains(&"/robot_model".to_owned()));
    assert!(panel_topics.contains(&"/events".to_owned()));
    for topic in &panel_topics {
        assert!(
            mapped.contains(&topic.as_str()),
            "layout topic {topic} is not mapped"
        );
    }

    let schema = VacuumView::get_schema().expect("schema");
    let set = FileDescriptorSet::decode(schema.data.as_ref()).expect("descriptor set");
    let vacuum_fields: Vec<String> = set
        .file
        .iter()
        .flat_map(|file| &file.message_type)
        .filter(|message| message.name() == "VacuumView")
        .flat_map(|message| &message.field)
        .map(|field| field.name().to_owned())
        .collect();
    assert!(!plot_paths.is_empty());
    for path in &plot_paths {
        let (topic, rest) = path.split_once('.').expect("topic.field");
        assert!(
            mapped.contains(&topic),
            "plot path {path}: topic not mapped"
        );
        if topic == topics::VACUUM.name {
            assert!(
                vacuum_fields.iter().any(|field| field == rest),
                "plot path {path}: no field {rest} in {vacuum_fields:?}"
            );
        } else {
            assert!(
                topics::ARM_JOINTS.iter().any(|joints| joints.name == topic),
                "plot path {path}: only /vacuum and /armN/joints are plotted"
            );
            assert!(
                JOINT_NAMES
                    .iter()
                    .any(|name| rest == format!("joints[:]{{name==\"{name}\"}}.position")),
                "plot path {path}: not a joint of {JOINT_NAMES:?}"
            );
        }
    }
}
