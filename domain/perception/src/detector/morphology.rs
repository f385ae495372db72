//! Binary morphology with a 3x3 square structuring element on a row-major `u8` mask (0 / 1).
//!
//! Neighbours outside the image are ignored, so erosion does not eat objects that touch the image
//! border and dilation does not grow from outside.

/// `dst = erode(src)` (a cell stays set only when all its 3x3 neighbours are set).
pub(crate) fn erode(
    src: &[u8],
    width: usize,
    height: usize,
    scratch: &mut Vec<u8>,
    dst: &mut Vec<u8>,
) {
    filter3x3(src, width, height, scratch, dst, u8::min);
}

/// `dst = dilate(src)` (a cell becomes set when any 3x3 neighbour is set).
pub(crate) fn dilate(
    src: &[u8],
    width: usize,
    height: usize,
    scratch: &mut Vec<u8>,
    dst: &mut Vec<u8>,
) {
    filter3x3(src, width, height, scratch, dst, u8::max);
}

/// Opening (erode, then dilate) in place: removes specks narrower than 3 cells.
pub(crate) fn open(
    mask: &mut Vec<u8>,
    width: usize,
    height: usize,
    a: &mut Vec<u8>,
    b: &mut Vec<u8>,
) {
    erode(mask, width, height, a, b);
    dilate(b, width, height, a, mask);
}

/// Closing (dilate, then erode) in place: fills gaps narrower than 3 cells.
pub(crate) fn close(
    mask: &mut Vec<u8>,
    width: usize,
    height: usize,
    a: &mut Vec<u8>,
    b: &mut Vec<u8>,
) {
    dilate(mask, width, height, a, b);
    erode(b, width, height, a, mask);
}

/// Separable 3x3 min/max filter: a horizontal pass into `scratch`, a vertical pass into `dst`.
/// Generic over `op` so it inlines and vectorizes.
fn filter3x3<F: Fn(u8, u8) -> u8 + Copy>(
    src: &[u8],
    width: usize,
    height: usize,
    scratch: &mut Vec<u8>,
    dst: &mut Vec<u8>,
    op: F,
) {
    let n = width * height;
    scratch.clear();
    scratch.resize(n, 0);
    dst.clear();
    dst.resize(n, 0);
    if n == 0 || src.len() < n {
        return;
    }
    for (row_in, row_out) in src[..n]
        .chunks_exact(width)
        .zip(scratch.chunks_exact_mut(width))
    {
        if width == 1 {
            row_out[0] = row_in[0];
            continue;
        }
        row_out[0] = op(row_in[0], row_in[1]);
        for (out, window) in row_out[1..width - 1].iter_mut().zip(row_in.windows(3)) {
            *out = op(op(window[0], window[1]), window[2]);
        }
        row_out[width - 1] = op(row_in[width - 2], row_in[width - 1]);
    }
    for y in 0..height {
        let row = y * width;
        let current = &scratch[row..row + width];
        let above = if y > 0 {
            &scratch[row - width..row]
        } else {
            current
        };
        let below = if y + 1 < height {
            &scratch[row + width..row + 2 * width]
        } else {
            current
        };
        for (((out, &c), &a), &b) in dst[row..row + width]
            .iter_mut()
            .zip(current)
            .zip(above)
            .zip(below)
        {
            *out = op(op(a, c), b);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn from_rows(rows: &[&str]) -> (Vec<u8>, usize, usize) {
        let width = rows[0].len();
        let mask = rows
            .iter()
            .flat_map(|r| r.bytes().map(|b| u8::from(b == b'#')))
            .collect();
        (mask, width, rows.len())
    }

    #[test]
    fn opening_removes_speck_and_keeps_block() {
        let (mut mask, w, h) = from_rows(&[
            "#.......", //
            "........", //
            "...###..", //
            "...###..", //
            "...###..", //
        ]);
        let (mut a, mut b) = (Vec::new(), Vec::new());
        open(&mut mask, w, h, &mut a, &mut b);
        let (expected, _, _) = from_rows(&[
            "........", //
            "........", //
            "...###..", //
            "...###..", //
            "...###..", //
        ]);
        assert_eq!(mask, expected);
    }

    #[test]
    fn closing_fills_one_cell_gap() {
        let (mut mask, w, h) = from_rows(&[
            "..........", //
            "..........", //
            "..###.##..", //
            "..######..", //
            "..######..", //
            "..........", //
            "..........", //
        ]);
        let (mut a, mut b) = (Vec::new(), Vec::new());
        let before = mask.clone();
        close(&mut mask, w, h, &mut a, &mut b);
        assert_eq!(mask[2 * w + 5], 1, "gap filled");
        let mut expected = before;
        expected[2 * w + 5] = 1;
        assert_eq!(mask, expected, "nothing else changes");
    }
}
