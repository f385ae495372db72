//! Checkerboard inner corners found in a grey image: the image side of the target-based
//! LiDAR-camera calibration ([fusion sec. II-C-1], "checkerboard corners found in
//! the image and in the point cloud"; the cloud side is [`crate::lidar::cloud_corners`]).
//!
//! The detector sees only the pixels and the board's corner counts, never a pose:
//! 1. x-corner response: the ChESS detector (Bennett and Lasenby) on a ring of 16 pixels of
//!    radius 5 around each pixel: opposite ring samples of an x-corner have the same colour and
//!    samples a quarter turn apart the other one (sum response), an edge makes opposite samples
//!    differ (difference response) and a blob shifts the ring mean from the centre (mean
//!    response); response = sum - difference - 16 * mean.
//! 2. non-maximum suppression in a 9 x 9 window over a response threshold; each candidate keeps
//!    the second circular harmonic of its ring, whose phase gives the corner's orientation and
//!    polarity (which diagonal is bright): neighbours along a grid line have opposite polarity,
//!    diagonal ones the same.
//! 3. sub-pixel refinement (the idea of OpenCV's `cornerSubPix`): at the true corner `q` every
//!    image gradient `g_p` in a window is orthogonal to `p - q` (on a flat square the gradient
//!    is zero, on an edge through `q` it is normal to the edge), so `q` solves the 2 x 2 system
//!    `sum w g g^T q = sum w g g^T p`, iterated with the window recentred at the new estimate.
//!    Candidates are refined when the grid search first looks at them (a candidate that does not
//!    converge is no corner), and the grid's corners once more at the end with a window scaled
//!    to the local square size.
//! 4. grid: a seed candidate, its nearest neighbours of opposite polarity along its two edge
//!    directions and the fourth corner of that square; then the grid grows one step at a time,
//!    predicting each new corner from the corners already found (quadratic extrapolation along a
//!    line, or the step of a neighbouring line) and taking the nearest candidate of the expected
//!    polarity within a quarter of a square; it stops at the board's corner counts.
//! 5. order: the board frame convention of [`Checkerboard::corners_m`] (row by row, x to the
//!    right, y down). The pattern is symmetric under a half turn; the board is upright (lower
//!    edge roughly level, as the paper asks), so the image directions settle it, as the cloud
//!    side does with the LiDAR's up.
//! 6. checks of a complete grid: the pattern one square beyond the outer corners lies in the
//!    image (a larger board partly in view could not be told apart), every corner lies on the
//!    smooth curves through its row and column neighbours, and the squares between the corners
//!    have the board's colours with a minimum contrast (a grid one square off has them swapped).
//!    A grid failing a check is set aside and the next seed tried; its reason is reported when
//!    no grid passes.

use crate::lidar::board_image::GreyImage;
use crate::lidar::checkerboard::Checkerboard;
use std::cell::RefCell;
use std::collections::BTreeMap;

/// Detector settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageCornerConfig {
    /// Smallest ChESS response of a candidate (an ideal corner of contrast `c` gives about `8 c`).
    pub min_response: f32,
    /// Smallest grey-level difference between the white and the black squares.
    pub min_contrast_grey: f64,
    /// Candidates kept (strongest first).
    pub max_candidates: usize,
    /// Candidates tried as the seed of a grid (strongest first).
    pub max_seeds: usize,
    /// Largest half size of the sub-pixel window, pixels (smaller for small squares).
    pub subpixel_half_window_px: usize,
    /// Largest distance of a corner from the curves through its neighbours, share of a square.
    pub max_irregularity: f64,
}

impl Default for ImageCornerConfig {
    fn default() -> Self {
        Self {
            min_response: 60.0,
            min_contrast_grey: 40.0,
            max_candidates: 4000,
            max_seeds: 400,
            subpixel_half_window_px: 5,
            max_irregularity: 0.08,
        }
    }
}

/// The board's corners found in one image.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageCornerDetection {
    /// Inner corners, row by row like [`Checkerboard::corners_m`], pixels.
    pub corners_px: Vec<[f64; 2]>,
    /// Corner candidates in the whole image.
    pub candidates: usize,
    /// Mean grey level of the white and of the black squares.
    pub bright_grey: f64,
    pub dark_grey: f64,
}

/// Why the board's corners were not found.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ImageCornerError {
    /// The pixel buffer does not match the stated size.
    #[error("image of {width_px} x {height_px} px needs {needed} bytes, the buffer holds {len}")]
    ImageSize {
        width_px: usize,
        height_px: usize,
        len: usize,
        needed: usize,
    },
    /// Fewer x-corner candidates than the board has corners.
    #[error(
        "only {found} corner candidates in the image, the board has {needed} inner corners \
         (no board in view, or too little contrast)"
    )]
    TooFewCandidates { found: usize, needed: usize },
    /// No complete grid among the candidates.
    #[error(
        "checkerboard grid not found: found {found} of {expected} corners ({candidates} \
         candidates in the image)"
    )]
    GridNotFound {
        found: usize,
        expected: usize,
        candidates: usize,
    },
    /// The pattern reaches beyond the image.
    #[error(
        "the board reaches the image edge: found {found} of {expected} corners and the pattern \
         continues out of the image"
    )]
    BoardAtImageEdge { found: usize, expected: usize },
    /// A complete grid with rows and columns swapped (a board held sideways).
    #[error(
        "grid of {columns} x {rows} corners, the board has {expected_columns} x {expected_rows} \
         (held sideways?)"
    )]
    WrongShape {
        columns: usize,
        rows: usize,
        expected_columns: usize,
        expected_rows: usize,
    },
    /// A corner off the curves through its neighbours (a false corner taken into the grid).
    #[error(
        "grid corners do not line up: corner ({column}, {row}) lies {off_px:.1} px off the \
         curves through its neighbours (at most {allowed_px:.1} px for this square size)"
    )]
    IrregularGrid {
        column: usize,
        row: usize,
        off_px: f64,
        allowed_px: f64,
    },
    /// White and black squares are too alike.
    #[error(
        "too little contrast on the board: black squares {dark:.0}, white squares {bright:.0} \
         grey levels, need a difference of at least {needed:.0}"
    )]
    LowContrast { dark: f64, bright: f64, needed: f64 },
    /// The squares' colours are the opposite of the board's pattern.
    #[error(
        "the squares' colours are swapped against the board's pattern (squares that should be \
         black {dark:.0}, white {bright:.0} grey levels): a grid one square off, or a negative"
    )]
    SwappedColours { dark: f64, bright: f64 },
}

/// ChESS ring: 16 pixels at radius 5, counter-clockwise in the image (x right, y down).
const RING: [(isize, isize); 16] = [
    (5, 0),
    (5, 2),
    (4, 4),
    (2, 5),
    (0, 5),
    (-2, 5),
    (-4, 4),
    (-5, 2),
    (-5, 0),
    (-5, -2),
    (-4, -4),
    (-2, -5),
    (0, -5),
    (2, -5),
    (4, -4),
    (5, -2),
];
const RING_RADIUS_PX: usize = 5;
/// Half size of the non-maximum suppression window, pixels.
const NMS_HALF_PX: usize = 4;
/// Half size of the sub-pixel window for candidates, pixels.
const CANDIDATE_HALF_WINDOW_PX: usize = 4;
/// Distance of grid neighbours, pixels: closer than this is one corner, farther is not a
/// neighbour on any board a camera resolves.
const MIN_SPACING_PX: f64 = 8.0;
const MAX_SPACING_PX: f64 = 400.0;
/// Neighbours looked at when choosing a seed's square.
const SEED_NEIGHBOURS: usize = 8;
/// A new corner must lie within this share of a square from its prediction.
const SEARCH_SHARE: f64 = 0.25;
/// Largest angle between a seed's step and its edge direction, radians.
const EDGE_TOLERANCE_RAD: f64 = 0.45;
/// Cosine of the orientation difference: below `-POLARITY` opposite, above `POLARITY` the same.
const POLARITY: f64 = 0.5;
/// Keep predictions this far inside the image, pixels.
const EDGE_MARGIN_PX: f64 = (RING_RADIUS_PX + 1) as f64;
/// Keep the pattern's outline this far inside the image, pixels.
const OUTLINE_MARGIN_PX: f64 = 2.0;

/// An x-corner candidate.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    /// Pixel of the response maximum.
    pixel: [f64; 2],
    response: f32,
    /// Unit second circular harmonic of the ring: orientation and polarity.
    harmonic: [f64; 2],
}

impl Candidate {
    /// Cosine between two candidates' harmonics: +1 same polarity, -1 opposite.
    fn polarity(&self, other: &Candidate) -> f64 {
        self.harmonic[0] * other.harmonic[0] + self.harmonic[1] * other.harmonic[1]
    }

    /// The two edge directions through the corner (line angles, radians). The harmonic's phase
    /// is twice the direction of the bright diagonal; the edges lie a quarter turn either side.
    fn edge_angles_rad(&self) -> [f64; 2] {
        let bright = 0.5 * self.harmonic[1].atan2(self.harmonic[0]);
        let quarter = std::f64::consts::FRAC_PI_4;
        [bright + quarter, bright - quarter]
    }
}

/// Finds the inner corners of `board` in `image`.
pub fn detect_image_corners(
    image: &GreyImage,
    board: &Checkerboard,
    config: &ImageCornerConfig,
) -> Result<ImageCornerDetection, ImageCornerError> {
    let needed = image.width_px * image.height_px;
    if image.pixels.len() != needed {
        return Err(ImageCornerError::ImageSize {
            width_px: image.width_px,
            height_px: image.height_px,
            len: image.pixels.len(),
            needed,
        });
    }
    let expected = board.corner_count();
    let candidates = find_candidates(image, config);
    tracing::trace!(candidates = candidates.len(), "x-corner candidates");
    let search = GridSearch::new(image, board, &candidates);
    let mut best = GrownGrid::default();
    let mut rejected = None;
    for seed in 0..candidates.len().min(config.max_seeds) {
        let Some(grid) = search.grow_from(seed) else {
            continue;
        };
        if grid.cells.len() == expected {
            match search.finish(&grid, board, config) {
                Ok(detection) => return Ok(detection),
                Err(error) => {
                    tracing::trace!(seed, %error, "complete grid rejected");
                    rejected.get_or_insert(error);
                    continue;
                }
            }
        }
        let larger = grid.cells.len() > best.cells.len();
        if larger || (grid.cells.len() == best.cells.len() && grid.hit_edge) {
            best = grid;
        }
    }
    Err(if let Some(error) = rejected {
        error
    } else if best.hit_edge && best.cells.len() >= 4 {
        ImageCornerError::BoardAtImageEdge {
            found: best.cells.len(),
            expected,
        }
    } else if candidates.len() < expected {
        ImageCornerError::TooFewCandidates {
            found: candidates.len(),
            needed: expected,
        }
    } else {
        ImageCornerError::GridNotFound {
            found: best.cells.len(),
            expected,
            candidates: candidates.len(),
        }
    })
}

/// Steps 1-2: ChESS response, non-maximum suppression, strongest first.
fn find_candidates(image: &GreyImage, config: &ImageCornerConfig) -> Vec<Candidate> {
    let (width, height) = (image.width_px, image.height_px);
    let r = RING_RADIUS_PX;
    let n = NMS_HALF_PX;
    if width <= 2 * (r + n) + 1 || height <= 2 * (r + n) + 1 {
        return Vec::new();
    }
    let px = &image.pixels;
    let offsets: Vec<isize> = RING
        .iter()
        .map(|&(dx, dy)| dy * width as isize + dx)
        .collect();
    let mut response = vec![f32::MIN; width * height];
    for v in r..height - r {
        for u in r..width - r {
            let centre = v * width + u;
            let mut s = [0i32; 16];
            for (value, offset) in s.iter_mut().zip(&offsets) {
                *value = i32::from(px[(centre as isize + offset) as usize]);
            }
            let sum_response: i32 = (0..4)
                .map(|n| (s[n] + s[n + 8] - s[n + 4] - s[n + 12]).abs())
                .sum();
            let diff_response: i32 = (0..8).map(|n| (s[n] - s[n + 8]).abs()).sum();
            let ring_sum: i32 = s.iter().sum();
            let local: i32 = i32::from(px[centre])
                + i32::from(px[centre - 1])
                + i32::from(px[centre + 1])
                + i32::from(px[centre - width])
                + i32::from(px[centre + width]);
            // 16 * |ring mean - local mean|.
            let mean_response = (5 * ring_sum - 16 * local).abs() as f32 / 5.0;
            response[centre] = (sum_response - diff_response) as f32 - mean_response;
        }
    }
    let angles: Vec<f64> = RING
        .iter()
        .map(|&(dx, dy)| (dy as f64).atan2(dx as f64))
        .collect();
    let mut candidates = Vec::new();
    for v in r + n..height - r - n {
        for u in r + n..width - r - n {
            let index = v * width + u;
            let value = response[index];
            if value < config.min_response {
                continue;
            }
            let mut is_max = true;
            'window: for nv in v - n..=v + n {
                for nu in u - n..=u + n {
                    let other = response[nv * width + nu];
                    let before = (nv, nu) < (v, u);
                    if other > value || (before && other == value) {
                        is_max = false;
                        break 'window;
                    }
                }
            }
            if !is_max {
                continue;
            }
            let mut harmonic = [0.0f64; 2];
            for ((dx, dy), angle) in RING.iter().zip(&angles) {
                let grey = f64::from(px[(index as isize + dy * width as isize + dx) as usize]);
                harmonic[0] += grey * (2.0 * angle).cos();
                harmonic[1] += grey * (2.0 * angle).sin();
            }
            let norm = harmonic[0].hypot(harmonic[1]);
            if norm <= 1e-9 {
                continue;
            }
            candidates.push(Candidate {
                pixel: [u as f64, v as f64],
                response: value,
                harmonic: [harmonic[0] / norm, harmonic[1] / norm],
            });
        }
    }
    candidates.sort_by(|a, b| b.response.total_cmp(&a.response));
    candidates.truncate(config.max_candidates);
    candidates
}

/// A grid grown from one seed: grid cell `(i, j)` -> candidate index.
#[derive(Debug, Clone, Default)]
struct GrownGrid {
    cells: BTreeMap<(i32, i32), usize>,
    /// A prediction fell outside the image.
    hit_edge: bool,
}

/// Step 4: candidate lookup by position, refined positions, grid growing.
struct GridSearch<'a> {
    image: &'a GreyImage,
    candidates: &'a [Candidate],
    /// Sub-pixel position of each candidate once looked at; `None` inside when it did not
    /// converge (not a corner).
    refined: RefCell<Vec<Option<Option<[f64; 2]>>>>,
    bucket_px: f64,
    buckets_x: usize,
    buckets: Vec<Vec<usize>>,
    /// Longest and shortest side of the corner grid.
    long_side: i32,
    short_side: i32,
}

impl<'a> GridSearch<'a> {
    fn new(image: &'a GreyImage, board: &Checkerboard, candidates: &'a [Candidate]) -> Self {
        let bucket_px = 32.0;
        let buckets_x = (image.width_px as f64 / bucket_px).ceil() as usize + 1;
        let buckets_y = (image.height_px as f64 / bucket_px).ceil() as usize + 1;
        let mut buckets = vec![Vec::new(); buckets_x * buckets_y];
        for (k, c) in candidates.iter().enumerate() {
            let bx = (c.pixel[0] / bucket_px) as usize;
            let by = (c.pixel[1] / bucket_px) as usize;
            if let Some(bucket) = buckets.get_mut(by * buckets_x + bx) {
                bucket.push(k);
            }
        }
        let (a, b) = (board.inner_columns as i32, board.inner_rows as i32);
        Self {
            image,
            candidates,
            refined: RefCell::new(vec![None; candidates.len()]),
            bucket_px,
            buckets_x,
            buckets,
            long_side: a.max(b),
            short_side: a.min(b),
        }
    }

    /// Sub-pixel position of candidate `k` (refined on first use); `None` when it is no corner.
    fn position(&self, k: usize) -> Option<[f64; 2]> {
        if let Some(known) = self.refined.borrow().get(k).copied().flatten() {
            return known;
        }
        let pixel = self.candidates.get(k)?.pixel;
        let position = refine_corner(self.image, pixel, CANDIDATE_HALF_WINDOW_PX);
        if let Some(slot) = self.refined.borrow_mut().get_mut(k) {
            *slot = Some(position);
        }
        position
    }

    /// Candidates whose refined position lies within `radius_px` of `point` and that pass
    /// `accept`, nearest first, with their positions.
    fn near(
        &self,
        point: [f64; 2],
        radius_px: f64,
        accept: impl Fn(usize) -> bool,
    ) -> Vec<(f64, usize, [f64; 2])> {
        // Refinement moves a candidate by at most its window.
        let reach = radius_px + CANDIDATE_HALF_WINDOW_PX as f64;
        let lo_x = ((point[0] - reach) / self.bucket_px).floor().max(0.0) as usize;
        let lo_y = ((point[1] - reach) / self.bucket_px).floor().max(0.0) as usize;
        let hi_x = ((point[0] + reach) / self.bucket_px).floor().max(0.0) as usize;
        let hi_y = ((point[1] + reach) / self.bucket_px).floor().max(0.0) as usize;
        let rows = self.buckets.len() / self.buckets_x;
        let mut found = Vec::new();
        for by in lo_y..=hi_y.min(rows.saturating_sub(1)) {
            for bx in lo_x..=hi_x.min(self.buckets_x - 1) {
                for &k in &self.buckets[by * self.buckets_x + bx] {
                    let pixel = self.candidates[k].pixel;
                    if (pixel[0] - point[0]).hypot(pixel[1] - point[1]) > reach || !accept(k) {
                        continue;
                    }
                    let Some(p) = self.position(k) else {
                        continue;
                    };
                    let distance = (p[0] - point[0]).hypot(p[1] - point[1]);
                    if distance <= radius_px {
                        found.push((distance, k, p));
                    }
                }
            }
        }
        found.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        found
    }

    /// A seed square: the seed, a neighbour along each edge direction, the fourth corner.
    fn seed_square(&self, seed: usize) -> Option<[usize; 4]> {
        let s = &self.candidates[seed];
        let origin = self.position(seed)?;
        let mut neighbours: Vec<(f64, usize)> = Vec::new();
        // Nearest first by pixel, then refined: only the closest few are refined.
        let lo_x = ((origin[0] - MAX_SPACING_PX) / self.bucket_px)
            .floor()
            .max(0.0) as usize;
        let lo_y = ((origin[1] - MAX_SPACING_PX) / self.bucket_px)
            .floor()
            .max(0.0) as usize;
        let hi_x = ((origin[0] + MAX_SPACING_PX) / self.bucket_px)
            .floor()
            .max(0.0) as usize;
        let hi_y = ((origin[1] + MAX_SPACING_PX) / self.bucket_px)
            .floor()
            .max(0.0) as usize;
        let rows = self.buckets.len() / self.buckets_x;
        for by in lo_y..=hi_y.min(rows.saturating_sub(1)) {
            for bx in lo_x..=hi_x.min(self.buckets_x - 1) {
                for &k in &self.buckets[by * self.buckets_x + bx] {
                    let p = self.candidates[k].pixel;
                    let distance = (p[0] - origin[0]).hypot(p[1] - origin[1]);
                    if k != seed
                        && (MIN_SPACING_PX..=MAX_SPACING_PX).contains(&distance)
                        && s.polarity(&self.candidates[k]) < -POLARITY
                    {
                        neighbours.push((distance, k));
                    }
                }
            }
        }
        neighbours.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let neighbours: Vec<(f64, usize, [f64; 2])> = neighbours
            .into_iter()
            .filter_map(|(_, k)| {
                let p = self.position(k)?;
                let distance = (p[0] - origin[0]).hypot(p[1] - origin[1]);
                (distance >= MIN_SPACING_PX).then_some((distance, k, p))
            })
            .take(SEED_NEIGHBOURS)
            .collect();
        let edges = s.edge_angles_rad();
        let along = |p: [f64; 2]| -> Option<usize> {
            let angle = (p[1] - origin[1]).atan2(p[0] - origin[0]);
            edges
                .iter()
                .position(|edge| line_angle_between(angle, *edge) < EDGE_TOLERANCE_RAD)
        };
        for &(da, a, pa) in &neighbours {
            let Some(edge_a) = along(pa) else { continue };
            for &(db, b, pb) in &neighbours {
                if b == a || along(pb) != Some(1 - edge_a) || !(0.5..=2.0).contains(&(db / da)) {
                    continue;
                }
                let diagonal = [pa[0] + pb[0] - origin[0], pa[1] + pb[1] - origin[1]];
                let radius = SEARCH_SHARE * da.min(db);
                let fourth = self.near(diagonal, radius, |k| {
                    k != seed && k != a && k != b && s.polarity(&self.candidates[k]) > POLARITY
                });
                if let Some(&(_, d, _)) = fourth.first() {
                    return Some([seed, a, b, d]);
                }
            }
        }
        None
    }

    /// Grows the grid of one seed square until no corner can be added.
    fn grow_from(&self, seed: usize) -> Option<GrownGrid> {
        let [s, a, b, d] = self.seed_square(seed)?;
        let mut grid = GrownGrid::default();
        grid.cells.insert((0, 0), s);
        grid.cells.insert((1, 0), a);
        grid.cells.insert((0, 1), b);
        grid.cells.insert((1, 1), d);
        let seed_corner = &self.candidates[seed];
        loop {
            let mut added = false;
            let known: Vec<(i32, i32)> = grid.cells.keys().copied().collect();
            for (i, j) in known {
                for (di, dj) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
                    let target = (i + di, j + dj);
                    if grid.cells.contains_key(&target) || !self.fits(&grid, target) {
                        continue;
                    }
                    let at =
                        |cell: (i32, i32)| grid.cells.get(&cell).and_then(|&k| self.position(k));
                    let Some(predicted) = predict(at, (i, j), (di, dj)) else {
                        continue;
                    };
                    let Some(from) = at((i, j)) else {
                        continue;
                    };
                    let step = (predicted[0] - from[0]).hypot(predicted[1] - from[1]);
                    if !inside(self.image, predicted, EDGE_MARGIN_PX) {
                        grid.hit_edge = true;
                        continue;
                    }
                    let same = (target.0 + target.1).rem_euclid(2) == 0;
                    let found = self
                        .near(predicted, SEARCH_SHARE * step, |k| {
                            let polarity = seed_corner.polarity(&self.candidates[k]);
                            let expected = if same {
                                polarity > POLARITY
                            } else {
                                polarity < -POLARITY
                            };
                            expected && !grid.cells.values().any(|&taken| taken == k)
                        })
                        .first()
                        .map(|&(_, k, _)| k);
                    if let Some(k) = found {
                        grid.cells.insert(target, k);
                        added = true;
                    }
                }
            }
            if !added {
                break;
            }
        }
        Some(grid)
    }

    /// True when adding `target` keeps the grid within the board's corner counts.
    fn fits(&self, grid: &GrownGrid, target: (i32, i32)) -> bool {
        let (mut lo_i, mut hi_i, mut lo_j, mut hi_j) = (target.0, target.0, target.1, target.1);
        for &(i, j) in grid.cells.keys() {
            lo_i = lo_i.min(i);
            hi_i = hi_i.max(i);
            lo_j = lo_j.min(j);
            hi_j = hi_j.max(j);
        }
        let (span_i, span_j) = (hi_i - lo_i + 1, hi_j - lo_j + 1);
        span_i.max(span_j) <= self.long_side && span_i.min(span_j) <= self.short_side
    }

    /// Steps 5-6 for a complete grid: order, final refinement and checks.
    fn finish(
        &self,
        grid: &GrownGrid,
        board: &Checkerboard,
        config: &ImageCornerConfig,
    ) -> Result<ImageCornerDetection, ImageCornerError> {
        let expected = board.corner_count();
        let ordered = self.order_grid(grid, board)?;
        let (columns, rows) = (board.inner_columns, board.inner_rows);
        let at = |points: &[[f64; 2]], i: usize, j: usize| points[j * columns + i];
        // The pattern one square beyond the outer corners must be inside the image.
        for j in 0..rows {
            for i in 0..columns {
                let di = edge_step(i, columns);
                let dj = edge_step(j, rows);
                if di == 0 && dj == 0 {
                    continue;
                }
                let here = at(&ordered, i, j);
                let inner = at(
                    &ordered,
                    i.saturating_add_signed(-di),
                    j.saturating_add_signed(-dj),
                );
                let outer = [2.0 * here[0] - inner[0], 2.0 * here[1] - inner[1]];
                if !inside(self.image, outer, OUTLINE_MARGIN_PX) {
                    return Err(ImageCornerError::BoardAtImageEdge {
                        found: expected,
                        expected,
                    });
                }
            }
        }
        // Final refinement, the window scaled to the local square size.
        let mut corners_px = Vec::with_capacity(expected);
        let mut spacing_px = Vec::with_capacity(expected);
        for j in 0..rows {
            for i in 0..columns {
                let here = at(&ordered, i, j);
                let mut spacing = f64::INFINITY;
                for (ni, nj) in [
                    (i.wrapping_sub(1), j),
                    (i + 1, j),
                    (i, j.wrapping_sub(1)),
                    (i, j + 1),
                ] {
                    if ni < columns && nj < rows {
                        let there = at(&ordered, ni, nj);
                        spacing = spacing.min((there[0] - here[0]).hypot(there[1] - here[1]));
                    }
                }
                let half = ((0.25 * spacing).round() as usize)
                    .clamp(2, config.subpixel_half_window_px.max(2));
                corners_px.push(refine_corner(self.image, here, half).unwrap_or(here));
                spacing_px.push(spacing);
            }
        }
        // Every corner on the smooth curves through its neighbours: the second difference along
        // its row and its column (perspective and lens bend these only slightly).
        for j in 0..rows {
            for i in 0..columns {
                let here = at(&corners_px, i, j);
                let mut off_px: f64 = 0.0;
                if i > 0 && i + 1 < columns {
                    let (a, b) = (at(&corners_px, i - 1, j), at(&corners_px, i + 1, j));
                    off_px = off_px
                        .max((0.5 * (a[0] + b[0]) - here[0]).hypot(0.5 * (a[1] + b[1]) - here[1]));
                }
                if j > 0 && j + 1 < rows {
                    let (a, b) = (at(&corners_px, i, j - 1), at(&corners_px, i, j + 1));
                    off_px = off_px
                        .max((0.5 * (a[0] + b[0]) - here[0]).hypot(0.5 * (a[1] + b[1]) - here[1]));
                }
                let allowed_px = config.max_irregularity * spacing_px[j * columns + i];
                if off_px > allowed_px {
                    return Err(ImageCornerError::IrregularGrid {
                        column: i,
                        row: j,
                        off_px,
                        allowed_px,
                    });
                }
            }
        }
        // Colours of the squares between the corners: square (i + 1, j + 1) of the board, black
        // when i + j is even.
        let (mut dark, mut bright) = ((0.0, 0usize), (0.0, 0usize));
        for j in 0..rows - 1 {
            for i in 0..columns - 1 {
                let quad = [
                    at(&corners_px, i, j),
                    at(&corners_px, i + 1, j),
                    at(&corners_px, i, j + 1),
                    at(&corners_px, i + 1, j + 1),
                ];
                let centre = [
                    quad.iter().map(|p| p[0]).sum::<f64>() / 4.0,
                    quad.iter().map(|p| p[1]).sum::<f64>() / 4.0,
                ];
                let mut grey = 0.0;
                for dv in -1..=1 {
                    for du in -1..=1 {
                        grey += sample(
                            self.image,
                            centre[0] + f64::from(du),
                            centre[1] + f64::from(dv),
                        );
                    }
                }
                let class = if (i + j) % 2 == 0 {
                    &mut dark
                } else {
                    &mut bright
                };
                class.0 += grey / 9.0;
                class.1 += 1;
            }
        }
        let dark_grey = dark.0 / dark.1.max(1) as f64;
        let bright_grey = bright.0 / bright.1.max(1) as f64;
        if dark_grey - bright_grey >= config.min_contrast_grey {
            return Err(ImageCornerError::SwappedColours {
                dark: dark_grey,
                bright: bright_grey,
            });
        }
        let contrast_grey = bright_grey - dark_grey;
        if contrast_grey.is_nan() || contrast_grey < config.min_contrast_grey {
            return Err(ImageCornerError::LowContrast {
                dark: dark_grey,
                bright: bright_grey,
                needed: config.min_contrast_grey,
            });
        }
        Ok(ImageCornerDetection {
            corners_px,
            candidates: self.candidates.len(),
            bright_grey,
            dark_grey,
        })
    }

    /// Step 5: the complete grid's refined positions in board order (row by row, x right,
    /// y down).
    fn order_grid(
        &self,
        grid: &GrownGrid,
        board: &Checkerboard,
    ) -> Result<Vec<[f64; 2]>, ImageCornerError> {
        let not_found = || ImageCornerError::GridNotFound {
            found: grid.cells.len(),
            expected: board.corner_count(),
            candidates: self.candidates.len(),
        };
        let lo_i = grid.cells.keys().map(|c| c.0).min().unwrap_or(0);
        let lo_j = grid.cells.keys().map(|c| c.1).min().unwrap_or(0);
        let mut cells = BTreeMap::new();
        for (&(i, j), &k) in &grid.cells {
            cells.insert(
                (i - lo_i, j - lo_j),
                self.position(k).ok_or_else(not_found)?,
            );
        }
        let span_i = cells.keys().map(|c| c.0).max().unwrap_or(0) + 1;
        let span_j = cells.keys().map(|c| c.1).max().unwrap_or(0) + 1;
        // Mean image step along each grid axis.
        let mean_step = |di: i32, dj: i32| {
            let mut sum = [0.0, 0.0];
            for (&(i, j), p) in &cells {
                if let Some(q) = cells.get(&(i + di, j + dj)) {
                    sum[0] += q[0] - p[0];
                    sum[1] += q[1] - p[1];
                }
            }
            sum
        };
        let step_i = mean_step(1, 0);
        let step_j = mean_step(0, 1);
        // Board x is the grid axis closer to the image's horizontal.
        let i_is_x = step_i[0].abs() * step_j[1].abs() >= step_i[1].abs() * step_j[0].abs();
        let (columns, rows, step_x, step_y) = if i_is_x {
            (span_i, span_j, step_i, step_j)
        } else {
            (span_j, span_i, step_j, step_i)
        };
        if columns as usize != board.inner_columns || rows as usize != board.inner_rows {
            return Err(ImageCornerError::WrongShape {
                columns: columns as usize,
                rows: rows as usize,
                expected_columns: board.inner_columns,
                expected_rows: board.inner_rows,
            });
        }
        let flip_x = step_x[0] < 0.0;
        let flip_y = step_y[1] < 0.0;
        let mut ordered = Vec::with_capacity(board.corner_count());
        for y in 0..rows {
            for x in 0..columns {
                let gx = if flip_x { columns - 1 - x } else { x };
                let gy = if flip_y { rows - 1 - y } else { y };
                let cell = if i_is_x { (gx, gy) } else { (gy, gx) };
                ordered.push(cells.get(&cell).copied().ok_or_else(not_found)?);
            }
        }
        Ok(ordered)
    }
}

/// `-1` on the first index, `1` on the last, `0` between.
fn edge_step(index: usize, count: usize) -> isize {
    if index == 0 {
        -1
    } else if index + 1 == count {
        1
    } else {
        0
    }
}

/// Where grid cell `from + step` should be: quadratic or linear extrapolation along the line
/// through `from`, else `from` plus the same step on a neighbouring line. `at` gives a cell's
/// position.
fn predict(
    at: impl Fn((i32, i32)) -> Option<[f64; 2]>,
    from: (i32, i32),
    step: (i32, i32),
) -> Option<[f64; 2]> {
    let back = |cell: (i32, i32), times: i32| (cell.0 - times * step.0, cell.1 - times * step.1);
    let p0 = at(from)?;
    if let Some(p1) = at(back(from, 1)) {
        if let Some(p2) = at(back(from, 2)) {
            return Some([
                3.0 * p0[0] - 3.0 * p1[0] + p2[0],
                3.0 * p0[1] - 3.0 * p1[1] + p2[1],
            ]);
        }
        return Some([2.0 * p0[0] - p1[0], 2.0 * p0[1] - p1[1]]);
    }
    let target = (from.0 + step.0, from.1 + step.1);
    for side in [(step.1, step.0), (-step.1, -step.0)] {
        let beside_from = (from.0 + side.0, from.1 + side.1);
        let beside_target = (target.0 + side.0, target.1 + side.1);
        if let (Some(q0), Some(q1)) = (at(beside_from), at(beside_target)) {
            return Some([p0[0] + q1[0] - q0[0], p0[1] + q1[1] - q0[1]]);
        }
    }
    None
}

/// Step 3: iterated gradient-orthogonality refinement of one corner; `None` when the system is
/// singular (no two edge directions in the window) or the corner wanders out of its window.
fn refine_corner(image: &GreyImage, start: [f64; 2], half_px: usize) -> Option<[f64; 2]> {
    const ITERATIONS: usize = 30;
    const CONVERGED_PX: f64 = 1e-3;
    let half = half_px as i32;
    let scale = f64::from(half * half).max(1.0);
    let mut q = start;
    for _ in 0..ITERATIONS {
        let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for dy in -half..=half {
            for dx in -half..=half {
                let (x, y) = (q[0] + f64::from(dx), q[1] + f64::from(dy));
                let gx = 0.5 * (sample(image, x + 1.0, y) - sample(image, x - 1.0, y));
                let gy = 0.5 * (sample(image, x, y + 1.0) - sample(image, x, y - 1.0));
                let w = (-f64::from(dx * dx + dy * dy) / scale).exp();
                let (gxx, gxy, gyy) = (w * gx * gx, w * gx * gy, w * gy * gy);
                a11 += gxx;
                a12 += gxy;
                a22 += gyy;
                b1 += gxx * x + gxy * y;
                b2 += gxy * x + gyy * y;
            }
        }
        // Both eigenvalues clearly positive: gradients in two directions (an edge alone leaves
        // the position along it undetermined).
        let det = a11 * a22 - a12 * a12;
        if !(det.is_finite() && det > 0.01 * (a11 + a22).powi(2)) {
            return None;
        }
        let next = [(a22 * b1 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det];
        let moved = (next[0] - q[0]).hypot(next[1] - q[1]);
        q = next;
        if (q[0] - start[0]).hypot(q[1] - start[1]) > half_px as f64 {
            return None;
        }
        if moved < CONVERGED_PX {
            break;
        }
    }
    Some(q)
}

/// Bilinear grey level at `(x, y)` (pixel centres at integers), clamped to the image.
fn sample(image: &GreyImage, x: f64, y: f64) -> f64 {
    if image.width_px == 0 || image.height_px == 0 {
        return 0.0;
    }
    let x = x.clamp(0.0, (image.width_px - 1) as f64);
    let y = y.clamp(0.0, (image.height_px - 1) as f64);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (u0, v0) = (x0 as usize, y0 as usize);
    let u1 = (u0 + 1).min(image.width_px - 1);
    let v1 = (v0 + 1).min(image.height_px - 1);
    let at = |u: usize, v: usize| f64::from(image.pixels[v * image.width_px + u]);
    (1.0 - fy) * ((1.0 - fx) * at(u0, v0) + fx * at(u1, v0))
        + fy * ((1.0 - fx) * at(u0, v1) + fx * at(u1, v1))
}

/// True when `point` lies at least `margin_px` inside the image.
fn inside(image: &GreyImage, point: [f64; 2], margin_px: f64) -> bool {
    point[0] >= margin_px
        && point[1] >= margin_px
        && point[0] <= image.width_px as f64 - 1.0 - margin_px
        && point[1] <= image.height_px as f64 - 1.0 - margin_px
}

/// Angle between two lines (directions modulo a half turn), radians in `[0, pi/2]`.
fn line_angle_between(a_rad: f64, b_rad: f64) -> f64 {
    let diff = (a_rad - b_rad).rem_euclid(std::f64::consts::PI);
    diff.min(std::f64::consts::PI - diff)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lidar::board_image::{BoardImageConfig, render_board_view};
    use crate::lidar::calibration::ImageCornerAccuracy;
    use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
    use rand::SeedableRng;
    use rand::rngs::SmallRng;

    fn true_corners(
        intrinsics: &CameraIntrinsics,
        board: &Checkerboard,
        pose: &RigidTransform,
    ) -> Vec<[f64; 2]> {
        board
            .corners_m()
            .into_iter()
            .map(|[x, y]| {
                let (u, v) = intrinsics
                    .project(pose.apply([x, y, 0.0]))
                    .expect("in front");
                [u, v]
            })
            .collect()
    }

    fn render(pose: &RigidTransform, config: &BoardImageConfig, seed: u64) -> GreyImage {
        let mut rng = SmallRng::seed_from_u64(seed);
        render_board_view(
            &CameraIntrinsics::tl460_rgb(),
            &Checkerboard::paper(),
            pose,
            config,
            &mut rng,
        )
        .expect("render")
    }

    #[test]
    fn all_corners_in_board_order_within_a_third_of_a_pixel_at_1_5_and_3_m() {
        let intrinsics = CameraIntrinsics::tl460_rgb();
        let board = Checkerboard::paper();
        let config = ImageCornerConfig::default();
        // (distance, tilt about x, tilt about y, roll, lateral offset)
        let placements = [
            (1.5, 0.0, 0.0, 0.0, [0.0, 0.0]),
            (1.5, 0.35, -0.45, 0.12, [0.3, -0.1]),
            (1.5, -0.5, 0.3, -0.1, [-0.4, 0.15]),
            (3.0, 0.0, 0.0, 0.05, [0.0, 0.0]),
            (3.0, 0.4, 0.45, -0.12, [-0.8, 0.3]),
            (3.0, -0.3, -0.5, 0.1, [0.9, -0.35]),
        ];
        for (k, (distance, tilt_x, tilt_y, roll, [x, y])) in placements.into_iter().enumerate() {
            let pose = RigidTransform::from_rpy_translation(tilt_x, tilt_y, roll, [x, y, distance]);
            let image = render(&pose, &BoardImageConfig::default(), 10 + k as u64);
            let detection = detect_image_corners(&image, &board, &config)
                .unwrap_or_else(|error| panic!("placement {k}: {error}"));
            let truth = true_corners(&intrinsics, &board, &pose);
            assert_eq!(detection.corners_px.len(), truth.len());
            let accuracy =
                ImageCornerAccuracy::measure([(detection.corners_px.as_slice(), truth.as_slice())])
                    .expect("corners compared");
            let (median, max) = (accuracy.median_px, accuracy.max_px);
            assert!(median < 0.3, "placement {k}: median error {median:.3} px");
            // In order: every corner is far closer to its own truth than to any neighbour's.
            assert!(max < 1.0, "placement {k}: max error {max:.3} px");
            assert!(detection.bright_grey - detection.dark_grey > 120.0);
        }
    }

    #[test]
    fn a_board_partly_outside_the_image_is_reported_at_the_edge() {
        let intrinsics = CameraIntrinsics::tl460_rgb();
        let board = Checkerboard::paper();
        // Board centre near the right edge at 1.5 m: about half the board leaves the image.
        let right_edge_m = (intrinsics.width_px as f64 - intrinsics.cx_px) / intrinsics.fx_px * 1.5;
        for (shift_m, seed) in [(0.0, 1), (0.1, 2), (-0.12, 3)] {
            let pose = RigidTransform::from_rpy_translation(
                0.1,
                0.2,
                0.05,
                [right_edge_m + shift_m, 0.1, 1.5],
            );
            let image = render(&pose, &BoardImageConfig::default(), seed);
            let error = detect_image_corners(&image, &board, &ImageCornerConfig::default())
                .expect_err("board cut by the image edge");
            assert!(
                matches!(error, ImageCornerError::BoardAtImageEdge { found, expected: 35 } if (4..35).contains(&found)),
                "shift {shift_m}: {error}"
            );
            assert!(error.to_string().contains("image edge"), "{error}");
        }
    }

    #[test]
    fn a_blank_image_has_no_candidates() {
        let board = Checkerboard::paper();
        let blank = GreyImage::filled(1920, 1080, 128);
        let error = detect_image_corners(&blank, &board, &ImageCornerConfig::default())
            .expect_err("nothing to find");
        assert_eq!(
            error,
            ImageCornerError::TooFewCandidates {
                found: 0,
                needed: 35
            }
        );
        let torn = GreyImage {
            width_px: 10,
            height_px: 10,
            pixels: vec![0; 99],
        };
        let error = detect_image_corners(&torn, &board, &ImageCornerConfig::default())
            .expect_err("short buffer");
        assert!(error.to_string().contains("needs 100 bytes"), "{error}");
    }

    #[test]
    fn a_board_with_too_little_contrast_is_named() {
        let board = Checkerboard::paper();
        let pose = RigidTransform::from_rpy_translation(0.1, -0.2, 0.03, [0.05, 0.0, 1.8]);
        // Grey paper, grey print: 25 grey levels apart, under the 40 needed.
        let faded = BoardImageConfig {
            white_grey: 135.0,
            black_grey: 110.0,
            ..BoardImageConfig::default()
        };
        let error = detect_image_corners(
            &render(&pose, &faded, 5),
            &board,
            &ImageCornerConfig::default(),
        )
        .expect_err("faded board");
        match error {
            ImageCornerError::LowContrast {
                dark,
                bright,
                needed,
            } => {
                assert!(bright - dark < needed && bright - dark > 10.0, "{error}");
            }
            other => panic!("expected low contrast, got {other}"),
        }
        // Barely printed at all: not even candidates for a grid.
        let blank = BoardImageConfig {
            white_grey: 130.0,
            black_grey: 126.0,
            ..BoardImageConfig::default()
        };
        let error = detect_image_corners(
            &render(&pose, &blank, 6),
            &board,
            &ImageCornerConfig::default(),
        )
        .expect_err("invisible board");
        assert!(
            matches!(
                error,
                ImageCornerError::TooFewCandidates { .. } | ImageCornerError::GridNotFound { .. }
            ),
            "{error}"
        );
    }

    #[test]
    fn a_negative_image_has_the_squares_colours_swapped() {
        let board = Checkerboard::paper();
        let pose = RigidTransform::from_rpy_translation(-0.2, 0.3, -0.05, [-0.1, 0.05, 2.2]);
        let mut image = render(&pose, &BoardImageConfig::default(), 8);
        image.pixels.iter_mut().for_each(|grey| *grey = 255 - *grey);
        let error = detect_image_corners(&image, &board, &ImageCornerConfig::default())
            .expect_err("negative");
        match error {
            ImageCornerError::SwappedColours { dark, bright } => {
                assert!(dark > 180.0 && bright < 80.0, "{error}");
            }
            other => panic!("expected swapped colours, got {other}"),
        }
    }

    #[test]
    fn a_board_held_sideways_is_refused() {
        let board = Checkerboard::paper();
        let pose = RigidTransform::from_rpy_translation(
            0.0,
            0.1,
            std::f64::consts::FRAC_PI_2,
            [0.0, 0.0, 2.0],
        );
        let error = detect_image_corners(
            &render(&pose, &BoardImageConfig::default(), 7),
            &board,
            &ImageCornerConfig::default(),
        )
        .expect_err("sideways");
        assert!(
            matches!(
                error,
                ImageCornerError::WrongShape {
                    columns: 5,
                    rows: 7,
                    ..
                }
            ),
            "{error}"
        );
    }
}
