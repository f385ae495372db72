//! `harvest dataset detector`: a training set for a learned apple detector, rendered by the
//! simulator with exact labels.
//!
//! Each world is a domain-randomised copy of a scenario ([`randomize`](mod@randomize)) rendered by the
//! simulator's ToF camera renderer at 1920x1080. The colour frame is written as the ONNX
//! detector sees it: resampled by perception's own letterbox ([`Letterbox::fill_input`]) to the
//! model's input scale, without the grey padding (640x360 for a 640 input), so training and
//! inference share one resampler. Labels come from the renderer's per-pixel label image: every
//! apple's box is the box of its visible pixels, with its visible fraction (measured as
//! `harvest eval perception` measures it, [`TruthMeter`]) and its conditions.
//!
//! Layout of `--out DIR`:
//! - `images/NNNNN.png`: the resampled colour frame;
//! - `labels/NNNNN.txt`: YOLO labels (`0 cx cy w h`, normalised) of the apples at least
//!   `--min-visible` visible, for any YOLO trainer;
//! - `masks/NNNNN.png`: the apples' visible pixels at the written image's size, 16-bit grey:
//!   0 where no apple is seen, else the apple's `mask_value` in the index (a segmentation
//!   trainer's instance masks; each pixel is the label of the full-resolution pixel under its
//!   centre);
//! - `index.jsonl`: one line per image: its seed, what was drawn, and every apple with any
//!   visible pixel (box in image pixels, visible fraction, conditions), so a trainer can ignore
//!   the barely visible ones instead of calling them background.

pub mod randomize;

use std::fs::File;
use std::io::{BufWriter, Write as _};
use std::path::{Path, PathBuf};

use harvest_perception::detector::yolo::letterbox::Letterbox;
use harvest_perception::frame::RgbView;
use harvest_sim::render_rgbd::apple_from_label;
use harvest_sim::{RgbdRenderer, World};
use serde::Serialize;
use thiserror::Error;
use tracing::info;

use crate::perception::truth::{FrameApple, TruthMeter};
use randomize::{Draw, randomize};

/// Arguments of `harvest dataset detector`.
#[derive(Debug, Clone, clap::Args)]
pub struct DetectorDatasetArgs {
    /// Output directory (created; existing files of the same names are overwritten).
    #[arg(long)]
    pub out: PathBuf,
    /// Worlds to render (one image each).
    #[arg(long, default_value_t = 1000)]
    pub worlds: u32,
    /// Seed of the first world; world i uses seed + i for the draw and the world. Keep it away
    /// from the evaluation's seeds (1..) so no evaluated world is trained on.
    #[arg(long, default_value_t = 100_000)]
    pub seed: u64,
    /// Scenario preset or TOML file the draws start from.
    #[arg(long, default_value = "default")]
    pub scenario: String,
    /// Square model input the frames are resampled for (the letterbox's scale), pixels.
    #[arg(long, default_value_t = 640)]
    pub input_size: u32,
    /// Apples at least this visible get a YOLO label.
    #[arg(long, default_value_t = 0.25)]
    pub min_visible: f64,
    /// Render the scenario as it is (no domain randomisation).
    #[arg(long)]
    pub no_randomize: bool,
}

/// Why a data set could not be written.
#[derive(Debug, Error)]
pub enum DatasetError {
    #[error("scenario {scenario}: {source}")]
    Scenario {
        scenario: String,
        source: Box<harvest_sim::ScenarioError>,
    },
    #[error("world seed {seed}: {source}")]
    World {
        seed: u64,
        source: harvest_sim::OrchardError,
    },
    #[error("rendering world seed {seed}: {source}")]
    Render {
        seed: u64,
        source: harvest_sim::RenderError,
    },
    #[error("writing {path}: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("writing {path}: {source}")]
    Image {
        path: PathBuf,
        source: image::ImageError,
    },
    #[error("--input-size {0} must be a multiple of 32 in 32..=4096")]
    InputSize(u32),
}

/// One apple of an index line.
#[derive(Debug, Clone, Serialize)]
struct LabelledApple {
    /// Box of the visible pixels in the written image: x_min, y_min, x_max, y_max (pixels).
    box_px: [f64; 4],
    visible_fraction: f64,
    visible_px_full_res: u64,
    over_exposed: bool,
    clustered: bool,
    occluded: bool,
    labelled: bool,
    /// This apple's pixels in `masks/NNNNN.png` hold this value (1 + its place in the line).
    mask_value: u16,
}

/// One line of `index.jsonl`.
#[derive(Debug, Clone, Serialize)]
struct IndexLine<'a> {
    image: String,
    seed: u64,
    width_px: u32,
    height_px: u32,
    draw: Option<&'a Draw>,
    apples: Vec<LabelledApple>,
}

/// What a run wrote.
#[derive(Debug, Clone, Copy, Default)]
pub struct DatasetSummary {
    pub images: u32,
    pub labelled_apples: u64,
    pub ignored_apples: u64,
}

fn write_error(path: &Path) -> impl FnOnce(std::io::Error) -> DatasetError + '_ {
    move |source| DatasetError::Write {
        path: path.to_path_buf(),
        source,
    }
}

/// Renders and writes the data set.
pub fn write_dataset(args: &DetectorDatasetArgs) -> Result<DatasetSummary, DatasetError> {
    if !(32..=4096).contains(&args.input_size) || !args.input_size.is_multiple_of(32) {
        return Err(DatasetError::InputSize(args.input_size));
    }
    let base = harvest_sim::process::load_scenario(&args.scenario).map_err(|source| {
        DatasetError::Scenario {
            scenario: args.scenario.clone(),
            source: Box::new(source),
        }
    })?;
    for dir in ["images", "labels", "masks"] {
        let path = args.out.join(dir);
        std::fs::create_dir_all(&path).map_err(write_error(&path))?;
    }
    let index_path = args.out.join("index.jsonl");
    let mut index = BufWriter::new(File::create(&index_path).map_err(write_error(&index_path))?);
    let mut summary = DatasetSummary::default();
    let mut rgb = Vec::new();
    let mut labels = Vec::new();
    let mut input = Vec::new();
    let mut truth = Vec::new();
    let mut renderer_slot: Option<(harvest_sim::scenario::CameraConfig, RgbdRenderer)> = None;
    for i in 0..args.worlds {
        let seed = args.seed.wrapping_add(u64::from(i));
        let (scenario, draw) = if args.no_randomize {
            (base.clone(), None)
        } else {
            let (scenario, draw) = randomize(&base, seed);
            (scenario, Some(draw))
        };
        let render = |source| DatasetError::Render { seed, source };
        let world = World::generate(&scenario, seed)
            .map_err(|source| DatasetError::World { seed, source })?;
        // A renderer per camera (its ray tables take ~0.1 s); the draws keep the base camera.
        let renderer = match &mut renderer_slot {
            Some((camera, renderer)) if *camera == scenario.camera => renderer,
            slot => {
                let renderer = RgbdRenderer::new(&scenario.camera).map_err(render)?;
                &mut slot.insert((scenario.camera.clone(), renderer)).1
            }
        };
        let intrinsics = *renderer.color_intrinsics();
        let (width, height) = (intrinsics.width_px, intrinsics.height_px);
        rgb.resize(3 * width as usize * height as usize, 0);
        labels.resize(width as usize * height as usize, 0);
        renderer.render_color(&world, &mut rgb).map_err(render)?;
        renderer
            .render_labels(&world, &mut labels)
            .map_err(render)?;
        let meter = TruthMeter::new(intrinsics, renderer.robot_from_color());
        meter.measure(&world, &labels, &mut truth);

        let letterbox = Letterbox::new(width, height, args.input_size);
        let view = RgbView {
            width_px: width,
            height_px: height,
            data: &rgb,
        };
        letterbox.fill_input(&view, &mut input, u8::MAX);
        let image = resized_region(&letterbox, &input);
        let name = format!("{i:05}");
        let image_path = args.out.join("images").join(format!("{name}.png"));
        image::save_buffer(
            &image_path,
            &image,
            letterbox.resized_width_px,
            letterbox.resized_height_px,
            image::ColorType::Rgb8,
        )
        .map_err(|source| DatasetError::Image {
            path: image_path.clone(),
            source,
        })?;

        let boxes = visible_boxes(&labels, width as usize, truth.len());
        let mask_values = mask_values(&boxes);
        let apples = label_apples(&letterbox, &truth, &boxes, &mask_values, args.min_visible);
        let mask = instance_mask(&labels, &letterbox, &mask_values);
        let mask_path = args.out.join("masks").join(format!("{name}.png"));
        image::ImageBuffer::<image::Luma<u16>, _>::from_raw(
            letterbox.resized_width_px,
            letterbox.resized_height_px,
            mask,
        )
        .ok_or_else(|| DatasetError::Write {
            path: mask_path.clone(),
            source: std::io::Error::other("mask size differs from the image's"),
        })?
        .save(&mask_path)
        .map_err(|source| DatasetError::Image {
            path: mask_path.clone(),
            source,
        })?;
        let label_path = args.out.join("labels").join(format!("{name}.txt"));
        let mut yolo = String::new();
        let (w, h) = (
            f64::from(letterbox.resized_width_px),
            f64::from(letterbox.resized_height_px),
        );
        for apple in &apples {
            if apple.labelled {
                let [x0, y0, x1, y1] = apple.box_px;
                yolo.push_str(&format!(
                    "0 {:.6} {:.6} {:.6} {:.6}\n",
                    (x0 + x1) / 2.0 / w,
                    (y0 + y1) / 2.0 / h,
                    (x1 - x0) / w,
                    (y1 - y0) / h
                ));
                summary.labelled_apples += 1;
            } else {
                summary.ignored_apples += 1;
            }
        }
        std::fs::write(&label_path, yolo).map_err(write_error(&label_path))?;
        let line = IndexLine {
            image: format!("images/{name}.png"),
            seed,
            width_px: letterbox.resized_width_px,
            height_px: letterbox.resized_height_px,
            draw: draw.as_ref(),
            apples,
        };
        let text = serde_json::to_string(&line).map_err(|e| DatasetError::Write {
            path: index_path.clone(),
            source: std::io::Error::other(e),
        })?;
        writeln!(index, "{text}").map_err(write_error(&index_path))?;
        summary.images += 1;
        if (i + 1) % 100 == 0 {
            info!(images = i + 1, of = args.worlds, "rendered");
        }
    }
    index.flush().map_err(write_error(&index_path))?;
    Ok(summary)
}

/// Width and height of the written image (the resized image inside the input), pixels.
fn resized_size(letterbox: &Letterbox) -> (usize, usize) {
    (
        letterbox.resized_width_px as usize,
        letterbox.resized_height_px as usize,
    )
}

/// The resized image inside the letterboxed `[1, 3, S, S]` input, as RGB8 rows.
fn resized_region(letterbox: &Letterbox, input: &[f32]) -> Vec<u8> {
    let size = letterbox.input_size_px as usize;
    let plane = size * size;
    let (w, h) = resized_size(letterbox);
    let (left, top) = (
        letterbox.pad_left_px as usize,
        letterbox.pad_top_px as usize,
    );
    let mut out = Vec::with_capacity(w * h * 3);
    for y in 0..h {
        for x in 0..w {
            let at = (top + y) * size + left + x;
            for channel in 0..3 {
                let value = input.get(channel * plane + at).copied().unwrap_or(0.0);
                out.push((value * 255.0).round().clamp(0.0, 255.0) as u8);
            }
        }
    }
    out
}

/// Per apple id, the half-open box `[u_min, v_min, u_max, v_max]` of its labelled pixels
/// (`None` when none is visible).
fn visible_boxes(labels: &[u32], width_px: usize, apples: usize) -> Vec<Option<[u32; 4]>> {
    let mut boxes: Vec<Option<[u32; 4]>> = vec![None; apples];
    if width_px == 0 {
        return boxes;
    }
    for (v, row) in labels.chunks_exact(width_px).enumerate() {
        for (u, &label) in row.iter().enumerate() {
            if let Some(id) = apple_from_label(label)
                && let Some(slot) = boxes.get_mut(id.0 as usize)
            {
                let (u, v) = (u as u32, v as u32);
                *slot = Some(match *slot {
                    None => [u, v, u + 1, v + 1],
                    Some([u0, v0, u1, v1]) => [u0.min(u), v0.min(v), u1.max(u + 1), v1.max(v + 1)],
                });
            }
        }
    }
    boxes
}

/// Per apple id, the value its pixels get in the mask image: 1 + its place among the visible
/// apples (the order of [`label_apples`]), 0 for an apple with no visible pixel.
fn mask_values(boxes: &[Option<[u32; 4]>]) -> Vec<u16> {
    let mut next = 0u16;
    boxes
        .iter()
        .map(|pixel_box| match pixel_box {
            Some(_) => {
                next = next.saturating_add(1);
                next
            }
            None => 0,
        })
        .collect()
}

/// The instance mask at the written image's size: each pixel is the mask value (`values`, per
/// apple id) of the apple whose label lies under its centre in the full-resolution label
/// image, else 0.
fn instance_mask(labels: &[u32], letterbox: &Letterbox, values: &[u16]) -> Vec<u16> {
    let (width, height) = (
        letterbox.image_width_px as usize,
        letterbox.image_height_px as usize,
    );
    let (out_w, out_h) = resized_size(letterbox);
    let source = |out: usize, limit: usize| {
        (((out as f64 + 0.5) / letterbox.scale) as usize).min(limit.saturating_sub(1))
    };
    let mut mask = Vec::with_capacity(out_w * out_h);
    for y in 0..out_h {
        let row = source(y, height) * width;
        for x in 0..out_w {
            let label = labels.get(row + source(x, width)).copied().unwrap_or(0);
            let value = apple_from_label(label)
                .and_then(|id| values.get(id.0 as usize).copied())
                .unwrap_or(0);
            mask.push(value);
        }
    }
    mask
}

/// The index entries of every visible apple, boxes in the written image's pixels.
fn label_apples(
    letterbox: &Letterbox,
    truth: &[FrameApple],
    boxes: &[Option<[u32; 4]>],
    mask_values: &[u16],
    min_visible: f64,
) -> Vec<LabelledApple> {
    truth
        .iter()
        .zip(boxes)
        .zip(mask_values)
        .filter_map(|((apple, pixel_box), &mask_value)| {
            let [u0, v0, u1, v1] = (*pixel_box)?;
            let (x0, y0) = (
                f64::from(u0) * letterbox.scale,
                f64::from(v0) * letterbox.scale,
            );
            let (x1, y1) = (
                f64::from(u1) * letterbox.scale,
                f64::from(v1) * letterbox.scale,
            );
            let visible_fraction = apple.visible_fraction();
            Some(LabelledApple {
                box_px: [x0, y0, x1, y1],
                visible_fraction,
                visible_px_full_res: apple.visible_px,
                over_exposed: apple.conditions.over_exposed,
                clustered: apple.conditions.clustered,
                occluded: apple.conditions.occluded,
                labelled: visible_fraction >= min_visible,
                mask_value,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_sim::render_rgbd::label::{APPLE_BASE as A0, LEAF as L};

    #[test]
    fn boxes_bound_each_apples_labelled_pixels() {
        #[rustfmt::skip]
        let labels = [
            L,  A0, L, L,
            A0, A0, L, A0 + 1,
            L,  L,  L, L,
        ];
        let boxes = visible_boxes(&labels, 4, 3);
        assert_eq!(boxes, vec![Some([0, 0, 2, 2]), Some([3, 1, 4, 2]), None]);
    }

    #[test]
    fn the_mask_samples_the_label_under_each_pixels_centre() {
        // Apple 0 has no visible pixel, so apple 1 is the first in the index (value 1), apple 2
        // the second; a 4x2 image halved (input 2 -> 2x1 resized).
        #[rustfmt::skip]
        let labels = [
            L,      A0 + 1, L, L,
            A0 + 1, A0 + 1, L, A0 + 2,
        ];
        let boxes = visible_boxes(&labels, 4, 3);
        assert_eq!(mask_values(&boxes), vec![0, 1, 2]);
        let letterbox = Letterbox::new(4, 2, 2);
        assert_eq!(
            (letterbox.resized_width_px, letterbox.resized_height_px),
            (2, 1)
        );
        // Centres (0.5, 0.5) and (1.5, 0.5) of the output fall on source pixels (1, 1) and (3, 1).
        assert_eq!(
            instance_mask(&labels, &letterbox, &mask_values(&boxes)),
            vec![1, 2]
        );
    }

    #[test]
    fn a_small_data_set_is_written_with_labels_inside_the_image() {
        let dir = std::env::temp_dir().join(format!("harvest-dataset-{}", std::process::id()));
        let args = DetectorDatasetArgs {
            out: dir.clone(),
            worlds: 2,
            seed: 100_000,
            scenario: "default".to_owned(),
            input_size: 320,
            min_visible: 0.25,
            no_randomize: false,
        };
        let summary = write_dataset(&args).expect("dataset");
        assert_eq!(summary.images, 2);
        assert!(summary.labelled_apples > 10, "{summary:?}");
        let image = image::open(dir.join("images/00001.png")).expect("png");
        assert_eq!((image.width(), image.height()), (320, 180));
        let index = std::fs::read_to_string(dir.join("index.jsonl")).expect("index");
        assert_eq!(index.lines().count(), 2);
        // Every labelled apple has pixels of its own in the mask, inside its box.
        let mask = image::open(dir.join("masks/00000.png"))
            .expect("mask png")
            .into_luma16();
        assert_eq!((mask.width(), mask.height()), (320, 180));
        let line: serde_json::Value =
            serde_json::from_str(index.lines().next().expect("line")).expect("json");
        let mut checked = 0;
        for apple in line["apples"].as_array().expect("apples") {
            let value = apple["mask_value"].as_u64().expect("mask_value") as u16;
            let b: Vec<f64> = apple["box_px"]
                .as_array()
                .expect("box")
                .iter()
                .map(|v| v.as_f64().expect("number"))
                .collect();
            let pixels: Vec<(u32, u32)> = mask
                .enumerate_pixels()
                .filter(|(_, _, p)| p.0[0] == value)
                .map(|(x, y, _)| (x, y))
                .collect();
            if apple["labelled"].as_bool() == Some(true) {
                assert!(!pixels.is_empty(), "{apple}");
                checked += 1;
            }
            for (x, y) in pixels {
                let (x, y) = (f64::from(x), f64::from(y));
                assert!(
                    x + 1.0 >= b[0] && x <= b[2] && y + 1.0 >= b[1] && y <= b[3],
                    "{apple}"
                );
            }
        }
        assert!(checked > 5, "{checked} labelled apples checked");
        let labels = std::fs::read_to_string(dir.join("labels/00000.txt")).expect("labels");
        for line in labels.lines() {
            let values: Vec<f64> = line
                .split_whitespace()
                .map(|v| v.parse().expect("number"))
                .collect();
            assert_eq!(values.len(), 5);
            assert!(
                values[1..].iter().all(|v| (0.0..=1.0).contains(v)),
                "{line}"
            );
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}
