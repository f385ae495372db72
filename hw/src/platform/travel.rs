//! The platform stages' travel limits.
//!
//! [dual-arm sec. 2] describes the platform movement module (two stepper stages, in-out
//! and up-down, with position feedback) but gives no stroke. Chosen here: 0.50 m in-out (from
//! the home stop, where the dropping module clears the canopy, to contact with it) and 0.80 m
//! up-down (enough to centre the arms' workspace on a fruiting zone of a 2-3 m tall wall),
//! both from 0 at the stop. A real installation overrides them with its measured strokes.

/// One of the two stages.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PlatformAxis {
    /// Horizontal, toward the canopy.
    InOut,
    /// Vertical.
    UpDown,
}

impl PlatformAxis {
    /// Both stages, in index order.
    pub const ALL: [PlatformAxis; 2] = [PlatformAxis::InOut, PlatformAxis::UpDown];

    /// Index in `[in_out, up_down]` arrays.
    pub fn index(self) -> usize {
        match self {
            Self::InOut => 0,
            Self::UpDown => 1,
        }
    }

    /// The stage's name in messages (`in-out`, `up-down`).
    pub fn name(self) -> &'static str {
        match self {
            Self::InOut => "in-out",
            Self::UpDown => "up-down",
        }
    }
}

impl std::fmt::Display for PlatformAxis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Travel of both stages, metres; each stage spans `[0, max]` from its stop.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlatformTravel {
    /// In-out stroke, m (choice: 0.50 m).
    pub in_out_max_m: f64,
    /// Up-down stroke, m (choice: 0.80 m).
    pub up_down_max_m: f64,
}

impl Default for PlatformTravel {
    fn default() -> Self {
        Self {
            in_out_max_m: 0.50,
            up_down_max_m: 0.80,
        }
    }
}

impl PlatformTravel {
    /// The stroke of `axis`, m.
    pub fn max_m(&self, axis: PlatformAxis) -> f64 {
        match axis {
            PlatformAxis::InOut => self.in_out_max_m,
            PlatformAxis::UpDown => self.up_down_max_m,
        }
    }

    /// True when `position_m` is finite and within `[0, max]` of `axis`.
    pub fn contains(&self, axis: PlatformAxis, position_m: f64) -> bool {
        position_m.is_finite() && (0.0..=self.max_m(axis)).contains(&position_m)
    }

    /// The first axis whose target is outside the travel, with that target.
    pub fn first_violation(&self, target_m: [f64; 2]) -> Option<(PlatformAxis, f64)> {
        PlatformAxis::ALL
            .into_iter()
            .map(|axis| (axis, target_m[axis.index()]))
            .find(|&(axis, value)| !self.contains(axis, value))
    }

    /// True when both strokes are finite and positive.
    pub fn is_valid(&self) -> bool {
        [self.in_out_max_m, self.up_down_max_m]
            .iter()
            .all(|m| m.is_finite() && *m > 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn travel_includes_its_ends_and_refuses_the_rest() {
        let travel = PlatformTravel::default();
        assert!(travel.is_valid());
        assert_eq!(travel.first_violation([0.0, 0.8]), None);
        assert_eq!(travel.first_violation([0.5, 0.0]), None);
        assert_eq!(
            travel.first_violation([-0.001, 0.1]),
            Some((PlatformAxis::InOut, -0.001))
        );
        assert_eq!(
            travel.first_violation([0.1, 0.81]),
            Some((PlatformAxis::UpDown, 0.81))
        );
        let Some((axis, value)) = travel.first_violation([0.1, f64::NAN]) else {
            panic!("NaN accepted");
        };
        assert_eq!(axis, PlatformAxis::UpDown);
        assert!(value.is_nan());
        assert!(
            !PlatformTravel {
                in_out_max_m: 0.0,
                up_down_max_m: 1.0
            }
            .is_valid()
        );
    }
}
