//! The calibration target of the target-based method ([fusion sec. III-C]): a
//! checkerboard of 7 x 5 inner corners and 5 cm squares, printed on white paper with a white
//! border, hung in the air with its lower edge level.
//!
//! Board frame: origin at the centre of the pattern, x to the right and y down as seen by the
//! sensors, z away from them (the board lies in z = 0). Square `(a, b)` (column `a`, row `b`,
//! counted from the top left) is black when `a + b` is even. Inner corner `(i, j)` is the corner
//! shared by squares `(i, j)` and `(i + 1, j + 1)`.

use serde::{Deserialize, Serialize};

/// A checkerboard target.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Checkerboard {
    /// Inner corners along a row (x).
    pub inner_columns: usize,
    /// Inner corners along a column (y).
    pub inner_rows: usize,
    /// Edge of one square, metres.
    pub square_m: f64,
    /// White border around the pattern, metres.
    pub border_m: f64,
}

impl Default for Checkerboard {
    fn default() -> Self {
        Self::paper()
    }
}

impl Checkerboard {
    /// The paper's board: 7 x 5 inner corners, 5 cm squares (a 2.5 cm white border assumed).
    pub fn paper() -> Self {
        Self {
            inner_columns: 7,
            inner_rows: 5,
            square_m: 0.05,
            border_m: 0.025,
        }
    }

    /// Width of the pattern without the border, metres.
    fn pattern_width_m(&self) -> f64 {
        (self.inner_columns + 1) as f64 * self.square_m
    }

    fn pattern_height_m(&self) -> f64 {
        (self.inner_rows + 1) as f64 * self.square_m
    }

    /// Outer width of the board, metres.
    pub fn width_m(&self) -> f64 {
        self.pattern_width_m() + 2.0 * self.border_m
    }

    /// Outer height of the board, metres.
    pub fn height_m(&self) -> f64 {
        self.pattern_height_m() + 2.0 * self.border_m
    }

    /// Number of inner corners.
    pub fn corner_count(&self) -> usize {
        self.inner_columns * self.inner_rows
    }

    /// Inner corner `(i, j)` in the board plane, metres.
    pub fn corner_m(&self, i: usize, j: usize) -> [f64; 2] {
        [
            (i + 1) as f64 * self.square_m - self.pattern_width_m() / 2.0,
            (j + 1) as f64 * self.square_m - self.pattern_height_m() / 2.0,
        ]
    }

    /// All inner corners, row by row (`j` outer, `i` inner), metres in the board plane.
    pub fn corners_m(&self) -> Vec<[f64; 2]> {
        (0..self.inner_rows)
            .flat_map(|j| (0..self.inner_columns).map(move |i| (i, j)))
            .map(|(i, j)| self.corner_m(i, j))
            .collect()
    }

    /// Colour of the board at `(x, y)` (board plane, metres): `Some(true)` white (border or white
    /// square), `Some(false)` black, `None` off the board.
    #[inline]
    pub fn is_white(&self, x_m: f64, y_m: f64) -> Option<bool> {
        if x_m.abs() > self.width_m() / 2.0 || y_m.abs() > self.height_m() / 2.0 {
            return None;
        }
        let column = (x_m + self.pattern_width_m() / 2.0) / self.square_m;
        let row = (y_m + self.pattern_height_m() / 2.0) / self.square_m;
        let columns = (self.inner_columns + 1) as f64;
        let rows = (self.inner_rows + 1) as f64;
        if column < 0.0 || row < 0.0 || column >= columns || row >= rows {
            return Some(true);
        }
        Some((column as usize + row as usize) % 2 == 1)
    }

    /// Checks the dimensions; the error names the field and value.
    pub fn validate(&self) -> Result<(), String> {
        if self.inner_columns < 2 || self.inner_rows < 2 {
            return Err(format!(
                "checkerboard needs at least 2 x 2 inner corners, got {} x {}",
                self.inner_columns, self.inner_rows
            ));
        }
        if !(self.square_m.is_finite() && self.square_m > 0.0) {
            return Err(format!(
                "checkerboard square_m = {} is not positive",
                self.square_m
            ));
        }
        if !(self.border_m.is_finite() && self.border_m >= 0.0) {
            return Err(format!(
                "checkerboard border_m = {} is negative",
                self.border_m
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_sit_between_squares_of_alternating_colour() {
        let board = Checkerboard::paper();
        assert_eq!(board.corner_count(), 35);
        assert!((board.width_m() - 0.45).abs() < 1e-12);
        assert!((board.height_m() - 0.35).abs() < 1e-12);
        let [x, y] = board.corner_m(0, 0);
        assert!((x + 0.15).abs() < 1e-12 && (y + 0.10).abs() < 1e-12);
        let e = 0.01;
        // Diagonal neighbours of a corner share a colour; adjacent ones differ.
        for [x, y] in board.corners_m() {
            let c = |dx: f64, dy: f64| board.is_white(x + dx, y + dy).expect("on board");
            assert_eq!(c(-e, -e), c(e, e));
            assert_ne!(c(-e, -e), c(e, -e));
        }
        // Top-left square is black, the border is white, outside is off the board.
        assert_eq!(board.is_white(-0.19, -0.14), Some(false));
        assert_eq!(board.is_white(-0.215, 0.0), Some(true));
        assert_eq!(board.is_white(0.3, 0.0), None);
    }
}
