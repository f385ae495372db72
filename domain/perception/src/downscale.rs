//! Box-filter downscaling of the colour image for the views of people (the console's camera
//! view, the Foxglove image): one implementation for both.

/// Averages `scale` x `scale` blocks of a row-major RGB8 image `source_width` pixels wide into
/// `out` (`size` = output width and height, px).
pub fn downscale_rgb(
    source: &[u8],
    source_width: usize,
    scale: usize,
    (width, height): (usize, usize),
    out: &mut Vec<u8>,
) {
    let scale = scale.max(1);
    out.clear();
    out.resize(width * height * 3, 0);
    let area = (scale * scale) as u32;
    let mut sums = vec![0u32; width * 3];
    for (row, out_row) in out.chunks_exact_mut(width * 3).enumerate() {
        sums.iter_mut().for_each(|sum| *sum = 0);
        for source_row in row * scale..(row + 1) * scale {
            let line = &source[source_row * source_width * 3..][..width * scale * 3];
            for (column, sum) in sums.chunks_exact_mut(3).enumerate() {
                for pixel in line[column * scale * 3..][..scale * 3].chunks_exact(3) {
                    sum[0] += u32::from(pixel[0]);
                    sum[1] += u32::from(pixel[1]);
                    sum[2] += u32::from(pixel[2]);
                }
            }
        }
        for (value, sum) in out_row.iter_mut().zip(&sums) {
            *value = ((sum + area / 2) / area) as u8;
        }
    }
}
