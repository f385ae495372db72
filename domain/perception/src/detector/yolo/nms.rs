//! Class-wise non-maximum suppression: a candidate is dropped when a higher-scoring candidate of
//! the same class overlaps it by more than the IoU threshold (Ultralytics' default,
//! `agnostic=False`). Fruit of two apple classes overlapping in the image are both kept; the
//! pipeline merges duplicates in 3D.

use super::decode::Candidate;

/// Intersection over union of two corner boxes `x1, y1, x2, y2`.
pub fn iou(a: &[f32; 4], b: &[f32; 4]) -> f32 {
    let width = (a[2].min(b[2]) - a[0].max(b[0])).max(0.0);
    let height = (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
    let intersection = width * height;
    let area = |r: &[f32; 4]| (r[2] - r[0]).max(0.0) * (r[3] - r[1]).max(0.0);
    let union = area(a) + area(b) - intersection;
    if union > 0.0 {
        intersection / union
    } else {
        0.0
    }
}

/// Keeps at most `max_kept` of `candidates` (sorted in place, best first), writing the indices
/// kept into `kept`, best first.
pub fn class_wise_nms(
    candidates: &mut [Candidate],
    iou_threshold: f32,
    max_kept: usize,
    kept: &mut Vec<usize>,
) {
    kept.clear();
    candidates.sort_by(|a, b| b.score.total_cmp(&a.score).then(a.anchor.cmp(&b.anchor)));
    for (index, candidate) in candidates.iter().enumerate() {
        if kept.len() >= max_kept {
            break;
        }
        let suppressed = kept.iter().any(|&k| {
            let other = &candidates[k];
            other.class_id == candidate.class_id
                && iou(&other.box_input, &candidate.box_input) > iou_threshold
        });
        if !suppressed {
            kept.push(index);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn candidate(anchor: usize, class_id: u32, score: f32, box_input: [f32; 4]) -> Candidate {
        Candidate {
            anchor,
            class_id,
            score,
            box_input,
        }
    }

    #[test]
    fn iou_of_known_boxes() {
        assert_eq!(iou(&[0.0, 0.0, 2.0, 2.0], &[0.0, 0.0, 2.0, 2.0]), 1.0);
        assert!((iou(&[0.0, 0.0, 2.0, 2.0], &[1.0, 0.0, 3.0, 2.0]) - 1.0 / 3.0).abs() < 1e-6);
        assert_eq!(iou(&[0.0, 0.0, 1.0, 1.0], &[2.0, 2.0, 3.0, 3.0]), 0.0);
        assert_eq!(iou(&[0.0, 0.0, 0.0, 0.0], &[0.0, 0.0, 0.0, 0.0]), 0.0);
    }

    #[test]
    fn overlapping_boxes_of_one_class_keep_the_best_and_other_classes_survive() {
        let mut candidates = vec![
            candidate(0, 0, 0.6, [0.0, 0.0, 10.0, 10.0]),
            candidate(1, 0, 0.9, [1.0, 0.0, 11.0, 10.0]), // IoU 0.82 with anchor 0
            candidate(2, 1, 0.5, [0.0, 0.0, 10.0, 10.0]), // other class: kept
            candidate(3, 0, 0.4, [20.0, 20.0, 30.0, 30.0]), // apart: kept
        ];
        let mut kept = Vec::new();
        class_wise_nms(&mut candidates, 0.45, 10, &mut kept);
        let anchors: Vec<usize> = kept.iter().map(|&k| candidates[k].anchor).collect();
        assert_eq!(anchors, [1, 2, 3]);
        class_wise_nms(&mut candidates, 0.45, 2, &mut kept);
        assert_eq!(kept.len(), 2);
        // A threshold of 1 suppresses nothing.
        class_wise_nms(&mut candidates, 1.0, 10, &mut kept);
        assert_eq!(kept.len(), 4);
    }
}
