//! The surface memory of one axial disk: the radial coordinate of the machined surface as a
//! function of the angle in the workpiece frame: the regeneration of the time-domain milling
//! simulation, in which each tooth cuts what the earlier teeth left instead of a nominal chip
//! (Smith & Tlusty, "An overview of modeling and simulation of the milling process", ASME J.
//! Eng. Ind. 113(2), 1991).
//!
//! The angle 0…2π is cut into [`BINS`] bins (0.35°) at θ_i = i·2π/BINS, with sin θ_i and
//! cos θ_i precomputed. A bin holds `cur`, the surface the teeth left there, and `prev`, its
//! value before the last tooth swept it. Angles are in bin units (x = φ·BINS/2π) so that the
//! index is the integer part.
//!
//! Reading at a tooth's angle x interpolates linearly between the bins i0 = ⌊x⌋ and i0+1. The
//! bin i0 may already have been swept by the same tooth in this pass (when its angle at the
//! previous step, x - Δx, was past θ_i0): then its value before that sweep, `prev`, is the one
//! the previous tooth left. Sweeping a tooth from x - Δx to x writes every bin it passed with
//! the radial coordinate of its tip at that bin, the tool axis interpolated linearly over the
//! step; a bin keeps the larger (deeper) of the two, since a tooth that did not reach the
//! surface cut nothing.

/// Bins over one revolution (a power of two, so wrapping is a mask).
pub const BINS: usize = 1024;
const MASK: usize = BINS - 1;

/// Bins kept up to date beyond each end of the material window, so that the interpolation of
/// a tooth just inside the window never reads a bin the teeth stopped writing.
const MARGIN: f64 = 2.0;

/// Sines, cosines and the material window of the bins, shared by all disks.
pub struct BinTable {
    sin: Vec<f64>,
    cos: Vec<f64>,
    swept: Vec<bool>,
    /// Material window in bin units, [start, end].
    window: (f64, f64),
}

impl BinTable {
    /// Bins for material between the entry and exit angles (rad).
    pub fn new(entry: f64, exit: f64) -> Self {
        let scale = BINS as f64 / std::f64::consts::TAU;
        let window = (entry * scale, exit * scale);
        let angles = (0..BINS).map(|i| i as f64 / scale);
        let mut table = Self {
            sin: angles.clone().map(f64::sin).collect(),
            cos: angles.map(f64::cos).collect(),
            swept: Vec::new(),
            window,
        };
        table.swept = (0..BINS)
            .map(|i| table.sweep_touches_window(i as f64, 0.0))
            .collect();
        table
    }

    /// Whether the angle x (bin units, in [0, BINS)) is in the material window.
    #[inline]
    pub fn in_window(&self, x: f64) -> bool {
        x >= self.window.0 && x <= self.window.1
    }

    /// Whether the swept interval [x - dx, x] touches the material window widened by the
    /// margin (x in [0, BINS), 0 ≤ dx < BINS).
    #[inline]
    pub fn sweep_touches_window(&self, x: f64, dx: f64) -> bool {
        let (s0, s1) = (self.window.0 - MARGIN, self.window.1 + MARGIN);
        let (a, m) = (x - dx, BINS as f64);
        (a <= s1 && x >= s0) || (a - m <= s1 && x - m >= s0) || (a + m <= s1 && x + m >= s0)
    }

    /// (sin, cos) of bin i.
    #[inline]
    fn sin_cos(&self, i: usize) -> (f64, f64) {
        (self.sin[i], self.cos[i])
    }
}

/// A tooth's sweep over one step: the tool axis at the previous and current instants and the
/// tooth's radius.
pub struct Sweep {
    pub from: [f64; 2],
    pub to: [f64; 2],
    pub radius: f64,
}

/// ⌊v⌋ for v > -BINS, without a libm call (the hot loop's floor).
#[inline]
pub fn floor(v: f64) -> i64 {
    (v + BINS as f64) as i64 - BINS as i64
}

/// The surface left on one disk.
#[derive(Clone)]
pub struct SurfaceMemory {
    /// (cur, prev) per bin, m.
    bins: Vec<[f64; 2]>,
}

impl SurfaceMemory {
    /// A memory holding `surface(i)` in bin i.
    pub fn new(surface: impl Fn(usize) -> f64) -> Self {
        Self {
            bins: (0..BINS)
                .map(|i| {
                    let r = surface(i);
                    [r, r]
                })
                .collect(),
        }
    }

    /// The surface the previous teeth left at angle x (bin units, [0, BINS)) for a tooth that
    /// moved by dx bins over the last step.
    #[inline]
    pub fn read(&self, x: f64, dx: f64) -> f64 {
        let i = x as usize;
        let frac = x - i as f64;
        let i0 = i & MASK;
        let b0 = self.bins[i0];
        let v0 = if frac >= dx { b0[1] } else { b0[0] };
        v0 + frac * (self.bins[(i0 + 1) & MASK][0] - v0)
    }

    /// Writes the bins the tooth passed from x - dx to x (bin units).
    #[inline]
    pub fn sweep(&mut self, table: &BinTable, x: f64, dx: f64, s: &Sweep) {
        if dx <= 0.0 {
            return;
        }
        let a = x - dx;
        let first = floor(a) + 1;
        let last = x as i64;
        let d = [s.to[0] - s.from[0], s.to[1] - s.from[1]];
        for i in first..=last {
            let idx = (i & MASK as i64) as usize;
            if !table.swept[idx] {
                continue;
            }
            let f = (i as f64 - a) / dx;
            let (sn, cs) = table.sin_cos(idx);
            let r = (s.from[0] + f * d[0]) * sn + (s.from[1] + f * d[1]) * cs + s.radius;
            let b = &mut self.bins[idx];
            b[1] = b[0];
            if r > b[0] {
                b[0] = r;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tooth_reads_the_previous_surface_not_its_own_sweep() {
        let table = BinTable::new(0.0, std::f64::consts::PI);
        let mut m = SurfaceMemory::new(|_| 1.0);
        // A tooth at radius 2 sweeps from bin 9.2 to 10.2, then moves on by 0.3 bin: bin 10 is
        // its own, so the read must still see the old surface (1.0) on both sides.
        let s = Sweep {
            from: [0.0, 0.0],
            to: [0.0, 0.0],
            radius: 2.0,
        };
        m.sweep(&table, 10.2, 1.0, &s);
        assert_eq!(m.read(10.5, 0.3), 1.0);
        // The next tooth, arriving from 9.9, sees the new surface in bin 10 and the old in 11.
        assert_eq!(m.read(10.5, 0.6), 1.5);
        // Away from the material nothing is written; next to it the margin is kept.
        m.sweep(&table, 700.5, 2.0, &s);
        assert_eq!(m.read(699.0, 0.0), 1.0);
        assert!(table.sweep_touches_window(1023.5, 1.0));
        assert!(table.sweep_touches_window(513.5, 1.0));
        assert!(!table.sweep_touches_window(600.0, 10.0));
    }
}
