//! 8-connected component labelling of a binary cell mask.

/// Connected components of the set cells, with each component's cells stored contiguously.
#[derive(Debug, Default)]
pub(crate) struct Components {
    labels: Vec<u32>,
    cells: Vec<u32>,
    ranges: Vec<(u32, u32)>,
    stack: Vec<u32>,
}

const UNLABELLED: u32 = u32::MAX;

impl Components {
    /// Labels the set cells of `mask` (row-major, `width * height`).
    pub(crate) fn label(&mut self, mask: &[u8], width: usize, height: usize) {
        let n = width * height;
        self.labels.clear();
        self.labels.resize(n, UNLABELLED);
        self.cells.clear();
        self.ranges.clear();
        if mask.len() < n {
            return;
        }
        for start in 0..n {
            if mask[start] == 0 || self.labels[start] != UNLABELLED {
                continue;
            }
            let label = self.ranges.len() as u32;
            let first = self.cells.len() as u32;
            self.labels[start] = label;
            self.stack.clear();
            self.stack.push(start as u32);
            while let Some(index) = self.stack.pop() {
                self.cells.push(index);
                let x = index as usize % width;
                let y = index as usize / width;
                let x_lo = x.saturating_sub(1);
                let x_hi = (x + 1).min(width - 1);
                let y_lo = y.saturating_sub(1);
                let y_hi = (y + 1).min(height - 1);
                for ny in y_lo..=y_hi {
                    for nx in x_lo..=x_hi {
                        let neighbour = ny * width + nx;
                        if mask[neighbour] != 0 && self.labels[neighbour] == UNLABELLED {
                            self.labels[neighbour] = label;
                            self.stack.push(neighbour as u32);
                        }
                    }
                }
            }
            self.ranges.push((first, self.cells.len() as u32));
        }
    }

    pub(crate) fn count(&self) -> usize {
        self.ranges.len()
    }

    /// Row-major cell indices of one component (empty for an unknown component).
    pub(crate) fn cells(&self, component: usize) -> &[u32] {
        match self.ranges.get(component) {
            Some(&(start, end)) => self.cells.get(start as usize..end as usize).unwrap_or(&[]),
            None => &[],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diagonal_cells_connect_and_separate_blobs_do_not() {
        #[rustfmt::skip]
        let mask = [
            1, 0, 0, 0, 1,
            0, 1, 0, 0, 1,
            0, 0, 0, 0, 0,
            1, 1, 0, 0, 0,
        ];
        let mut components = Components::default();
        components.label(&mask, 5, 4);
        assert_eq!(components.count(), 3);
        let mut sizes: Vec<usize> = (0..3).map(|c| components.cells(c).len()).collect();
        sizes.sort_unstable();
        assert_eq!(sizes, vec![2, 2, 2]);
        assert!(components.cells(7).is_empty());
    }
}
