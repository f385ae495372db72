//! Candidates from a YOLO predictions tensor `[1, C, N]`: per anchor the best class, kept when it
//! is an apple class at or above the score threshold.

/// One anchor's box and best class, before non-maximum suppression.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// Index of the anchor (column of the predictions tensor; selects the mask coefficients).
    pub anchor: usize,
    pub class_id: u32,
    /// Class score in [0, 1] (the export's sigmoided score).
    pub score: f32,
    /// Corners `x1, y1, x2, y2` in input pixels.
    pub box_input: [f32; 4],
}

/// Appends the candidates of `predictions` (`channels x anchors`, row-major: channel `c` of anchor
/// `n` at `c * anchors + n`; channels `0..4` the box `cx, cy, w, h`, then `classes` scores) to
/// `out`. An anchor's class is its highest-scoring class among all the model's classes (a fruit the
/// model thinks is more likely a leaf is not an apple); it is kept when that class is in
/// `apple_classes` and its score is at least `score_threshold`. `best` is scratch space.
#[allow(clippy::too_many_arguments)]
pub fn candidates(
    predictions: &[f32],
    anchors: usize,
    classes: usize,
    apple_classes: &[u32],
    score_threshold: f32,
    best: &mut Vec<(f32, u32)>,
    out: &mut Vec<Candidate>,
) {
    if predictions.len() < (4 + classes) * anchors {
        return;
    }
    best.clear();
    best.resize(anchors, (f32::NEG_INFINITY, 0));
    // Row by row: the tensor is channel-major, so this walks memory in order.
    for class in 0..classes {
        let row = &predictions[(4 + class) * anchors..(5 + class) * anchors];
        for (slot, &score) in best.iter_mut().zip(row) {
            if score > slot.0 {
                *slot = (score, class as u32);
            }
        }
    }
    let row = |channel: usize| &predictions[channel * anchors..(channel + 1) * anchors];
    let (cx, cy, w, h) = (row(0), row(1), row(2), row(3));
    for (anchor, &(score, class_id)) in best.iter().enumerate() {
        // NaN scores fail the comparison and are skipped.
        let above = score >= score_threshold;
        if !above || !apple_classes.contains(&class_id) {
            continue;
        }
        let (half_w, half_h) = (w[anchor] / 2.0, h[anchor] / 2.0);
        let box_input = [
            cx[anchor] - half_w,
            cy[anchor] - half_h,
            cx[anchor] + half_w,
            cy[anchor] + half_h,
        ];
        if box_input.iter().all(|v| v.is_finite()) && half_w > 0.0 && half_h > 0.0 {
            out.push(Candidate {
                anchor,
                class_id,
                score,
                box_input,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `[4 + classes, anchors]` tensor from per-anchor rows `(cx, cy, w, h, scores...)`.
    pub(crate) fn tensor(rows: &[Vec<f32>]) -> Vec<f32> {
        let channels = rows[0].len();
        let mut data = vec![0.0; channels * rows.len()];
        for (anchor, row) in rows.iter().enumerate() {
            for (channel, &value) in row.iter().enumerate() {
                data[channel * rows.len() + anchor] = value;
            }
        }
        data
    }

    #[test]
    fn the_best_class_decides_and_boxes_become_corners() {
        // Two classes: 0 apple, 1 leaf.
        let data = tensor(&[
            vec![100.0, 50.0, 20.0, 10.0, 0.9, 0.1], // apple
            vec![10.0, 10.0, 4.0, 4.0, 0.6, 0.7],    // more leaf than apple
            vec![30.0, 30.0, 8.0, 8.0, 0.2, 0.0],    // below threshold
            vec![30.0, 30.0, 0.0, 8.0, 0.9, 0.0],    // empty box
        ]);
        let mut best = Vec::new();
        let mut out = Vec::new();
        candidates(&data, 4, 2, &[0], 0.25, &mut best, &mut out);
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].anchor, 0);
        assert_eq!(out[0].class_id, 0);
        assert_eq!(out[0].box_input, [90.0, 45.0, 110.0, 55.0]);
        out.clear();
        candidates(&data, 4, 2, &[0, 1], 0.25, &mut best, &mut out);
        assert_eq!(out.iter().map(|c| c.class_id).collect::<Vec<_>>(), [0, 1]);
        // A tensor too short for its stated size yields nothing (never panics).
        out.clear();
        candidates(&data[..10], 4, 2, &[0], 0.25, &mut best, &mut out);
        assert!(out.is_empty());
    }
}
