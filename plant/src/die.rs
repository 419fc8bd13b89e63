//! The reference cam table: the tangent cylinder of a rotary-table stretch-bending
//! machine with an elliptical die (PLANT.md).
//!
//! The die is an ellipse with semi-axes `a`, `b` whose centre sits `e` from the table's
//! rotation centre. The support point is the point of the rotated die with a horizontal
//! tangent; its x coordinate at table angle θ is
//!
//! ```text
//! x_raw(θ) = e·cos θ + (a² − b²)·sin θ·cos θ / √(a²·sin²θ + b²·cos²θ)     [mm]
//! ```
//!
//! The nodes (every `step` degrees from `θ_0` to `θ_1`) are scaled linearly so that the
//! smallest node maps to `x_lo` and the largest to `x_hi` (the used stroke):
//! `x = x_lo + (x_raw − min)·(x_hi − x_lo)/(max − min)`. With the defaults (a = 900,
//! b = 600, e = 250 mm, 0…90° every 0.5°, 20…480 mm) the curve starts at 248.96 mm, peaks
//! at 480 mm at 33°, returns to 20 mm at 90°; the steepest chord is 11.99 mm/°.
//! `host-sim/scenarios/tangent_table.csv` is exactly [`DieTable::default`]'s output
//! (checked by a test).

use crate::camfile::CamCsv;
use std::path::PathBuf;

fn round6(x: f64) -> f64 {
    (x * 1e6).round() / 1e6
}

/// Parameters of the elliptical-die table.
#[derive(Clone, Debug, PartialEq)]
pub struct DieTable {
    /// Semi-axis a, mm.
    pub a_mm: f64,
    /// Semi-axis b, mm.
    pub b_mm: f64,
    /// Offset of the die centre from the rotation centre, mm.
    pub offset_mm: f64,
    /// First node, degrees.
    pub start_deg: f64,
    /// Last node, degrees.
    pub end_deg: f64,
    /// Number of nodes.
    pub nodes: usize,
    /// Position of the smallest node after scaling, mm.
    pub lo_mm: f64,
    /// Position of the largest node after scaling, mm.
    pub hi_mm: f64,
    /// Name of the slave column.
    pub axis: String,
}

impl Default for DieTable {
    fn default() -> Self {
        Self {
            a_mm: 900.0,
            b_mm: 600.0,
            offset_mm: 250.0,
            start_deg: 0.0,
            end_deg: 90.0,
            nodes: 181,
            lo_mm: 20.0,
            hi_mm: 480.0,
            axis: "tangent".into(),
        }
    }
}

impl DieTable {
    /// `x_raw(θ)`, mm, θ in degrees.
    pub fn x_raw_mm(&self, theta_deg: f64) -> f64 {
        let (s, c) = theta_deg.to_radians().sin_cos();
        let (a2, b2) = (self.a_mm * self.a_mm, self.b_mm * self.b_mm);
        self.offset_mm * c + (a2 - b2) * s * c / (a2 * s * s + b2 * c * c).sqrt()
    }

    /// The scaled node table (master in degrees, the slave in mm), rounded to 1e-6 (the
    /// CSV's 6 decimals: 1 nm) so the generated table and its CSV file are identical.
    pub fn table(&self) -> CamCsv {
        let n = self.nodes.max(2);
        let step = (self.end_deg - self.start_deg) / (n - 1) as f64;
        let master: Vec<f64> = (0..n)
            .map(|i| round6(self.start_deg + step * i as f64))
            .collect();
        let raw: Vec<f64> = master.iter().map(|&t| self.x_raw_mm(t)).collect();
        let lo = raw.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = raw.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let scale = (self.hi_mm - self.lo_mm) / (hi - lo);
        let x = raw
            .iter()
            .map(|r| round6(self.lo_mm + (r - lo) * scale))
            .collect();
        CamCsv {
            path: PathBuf::from("<elliptical die>"),
            axes: vec![self.axis.clone()],
            lines: (2..n + 2).collect(),
            header_line: 1,
            master,
            columns: vec![x],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_shape() {
        let t = DieTable::default().table();
        let x = &t.columns[0];
        assert_eq!(x.len(), 181);
        let (imax, max) =
            x.iter()
                .enumerate()
                .fold((0, f64::MIN), |b, (i, &v)| if v > b.1 { (i, v) } else { b });
        assert!((max - 480.0).abs() < 1e-9);
        assert!((t.master[imax] - 33.0).abs() < 1.0);
        assert!((x[180] - 20.0).abs() < 1e-9);
        let steep = x
            .windows(2)
            .map(|w| (w[1] - w[0]).abs() / 0.5)
            .fold(0.0, f64::max);
        assert!((steep - 12.0).abs() < 0.5, "steepest {steep} mm/°");
    }
}
