//! Generated test data with known ground truth: a flat sheet template and the same sheet with
//! folds, a rigid offset, and a scan sampled from it. Used by the tests, the `demo` command and
//! the benchmarks, so nothing generated is ever committed.

use crate::error::{FoldMatchError, Result};
use crate::limits::{MAX_PARAMETER, MAX_SHEET_SCAN_POINTS, MAX_SHEET_SIDE, MAX_SHEET_VERTICES};
use crate::math::{vec3, Vec3};
use nalgebra::Rotation3;

/// A tiny deterministic generator (SplitMix64), so generated cases are identical everywhere.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// Seeds the generator.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }
    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Standard normal (Box–Muller).
    pub fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

/// A regular triangulated grid of `nx × ny` vertices spanning `width × height` in the z = 0
/// plane, centered on the origin.
pub fn grid_sheet(nx: usize, ny: usize, width: f64, height: f64) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let mut v = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let x = width * (i as f64 / (nx - 1) as f64 - 0.5);
            let y = height * (j as f64 / (ny - 1) as f64 - 0.5);
            v.push([x, y, 0.0]);
        }
    }
    let mut f = Vec::with_capacity(2 * (nx - 1) * (ny - 1));
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let a = (j * nx + i) as u32;
            let (b, c, d) = (a + 1, a + nx as u32, a + nx as u32 + 1);
            f.push([a, b, d]);
            f.push([a, d, c]);
        }
    }
    (v, f)
}

/// How to fold and place the sheet, and how to scan it.
#[derive(Clone, Debug)]
pub struct SheetSpec {
    /// Grid vertices along x.
    pub nx: usize,
    /// Grid vertices along y.
    pub ny: usize,
    /// Sheet size along x.
    pub width: f64,
    /// Sheet size along y.
    pub height: f64,
    /// Fold height (z amplitude).
    pub fold_amplitude: f64,
    /// Number of fold waves across the sheet.
    pub folds: f64,
    /// Rigid rotation of the target, degrees about (1, 1, 1).
    pub rotation_degrees: f64,
    /// Rigid translation of the target.
    pub offset: [f64; 3],
    /// Scan points sampled uniformly on the folded surface (0: the folded vertices themselves).
    pub scan_points: usize,
    /// Gaussian noise added to the scan, relative to the sheet width.
    pub noise: f64,
    /// Seed of the sampling and noise.
    pub seed: u64,
}

impl Default for SheetSpec {
    fn default() -> Self {
        Self {
            nx: 41,
            ny: 41,
            width: 1.0,
            height: 1.0,
            fold_amplitude: 0.06,
            folds: 2.5,
            rotation_degrees: 8.0,
            offset: [0.03, -0.02, 0.04],
            scan_points: 0,
            noise: 0.0,
            seed: 1,
        }
    }
}

impl SheetSpec {
    /// Checks the sizes against [`crate::limits`] before anything is generated: nx and ny in
    /// 2..=[`MAX_SHEET_SIDE`], nx·ny ≤ [`MAX_SHEET_VERTICES`], scan_points ≤
    /// [`MAX_SHEET_SCAN_POINTS`]; and the real values finite (sizes positive, noise ≥ 0).
    pub fn validate(&self) -> Result<()> {
        for (name, n) in [("nx", self.nx), ("ny", self.ny)] {
            if !(2..=MAX_SHEET_SIDE).contains(&n) {
                return Err(FoldMatchError::parameter(
                    name,
                    n,
                    &format!("must be in 2..={MAX_SHEET_SIDE}"),
                ));
            }
        }
        if self.nx * self.ny > MAX_SHEET_VERTICES {
            return Err(FoldMatchError::parameter(
                "nx*ny",
                self.nx * self.ny,
                &format!("must be at most {MAX_SHEET_VERTICES}"),
            ));
        }
        if self.scan_points > MAX_SHEET_SCAN_POINTS {
            return Err(FoldMatchError::parameter(
                "scan_points",
                self.scan_points,
                &format!("must be in 0..={MAX_SHEET_SCAN_POINTS} (0: the folded vertices)"),
            ));
        }
        let reals = [
            ("width", self.width, true),
            ("height", self.height, true),
            ("fold_amplitude", self.fold_amplitude, false),
            ("folds", self.folds, false),
            ("rotation_degrees", self.rotation_degrees, false),
            ("offset[0]", self.offset[0], false),
            ("offset[1]", self.offset[1], false),
            ("offset[2]", self.offset[2], false),
            ("noise", self.noise, false),
        ];
        for (name, v, positive) in reals {
            if !v.is_finite() || v.abs() > MAX_PARAMETER {
                return Err(FoldMatchError::parameter(
                    name,
                    v,
                    "must be finite, at most 1e6 in size",
                ));
            }
            if positive && v <= 0.0 {
                return Err(FoldMatchError::parameter(name, v, "must be positive"));
            }
        }
        if self.noise < 0.0 {
            return Err(FoldMatchError::parameter(
                "noise",
                self.noise,
                "must be >= 0",
            ));
        }
        Ok(())
    }
}

/// A generated case: template, ground-truth fit (same vertex order) and scan.
#[derive(Clone, Debug)]
pub struct Case {
    /// Template vertices (flat sheet).
    pub template_vertices: Vec<[f64; 3]>,
    /// Template faces (also the ground truth's).
    pub faces: Vec<[u32; 3]>,
    /// Ground-truth positions of the template vertices.
    pub ground_truth: Vec<[f64; 3]>,
    /// Scan points.
    pub scan: Vec<[f64; 3]>,
}

/// The flat sheet and the same sheet with folds (waves along x whose amplitude varies along
/// y, plus a gentle drape), rotated and offset; the scan samples the folded surface.
pub fn folded_sheet(spec: &SheetSpec) -> Case {
    let (template, faces) = grid_sheet(spec.nx, spec.ny, spec.width, spec.height);
    let rot = Rotation3::from_axis_angle(
        &nalgebra::Unit::new_normalize(Vec3::new(1.0, 1.0, 1.0)),
        spec.rotation_degrees.to_radians(),
    );
    let offset = vec3(&spec.offset);
    let two_pi = 2.0 * std::f64::consts::PI;
    let ground_truth: Vec<[f64; 3]> = template
        .iter()
        .map(|p| {
            let (u, v) = (p[0] / spec.width + 0.5, p[1] / spec.height + 0.5);
            let envelope = 0.6 + 0.4 * (std::f64::consts::PI * v).sin();
            let z = spec.fold_amplitude * envelope * (two_pi * spec.folds * u).sin()
                + 0.5 * spec.fold_amplitude * (std::f64::consts::PI * u).sin();
            // Folding shortens the sheet along x a little (cloth is nearly inextensible).
            let x = p[0]
                * (1.0
                    - 0.5
                        * (spec.fold_amplitude * two_pi * spec.folds / spec.width).powi(2)
                        * 0.25);
            (rot * Vec3::new(x, p[1], z) + offset).into()
        })
        .collect();
    let mut rng = SplitMix64::new(spec.seed);
    let mut scan = if spec.scan_points == 0 {
        ground_truth.clone()
    } else {
        sample_surface(&ground_truth, &faces, spec.scan_points, &mut rng)
    };
    if spec.noise > 0.0 {
        let sigma = spec.noise * spec.width;
        for p in &mut scan {
            for c in p.iter_mut() {
                *c += sigma * rng.normal();
            }
        }
    }
    Case {
        template_vertices: template,
        faces,
        ground_truth,
        scan,
    }
}

/// An open tube about the y axis: `rows` rings of `around` vertices from `y.0` to `y.1`, of
/// radius `radius(y)`; two triangles per quad.
pub fn tube(
    around: usize,
    rows: usize,
    y: (f64, f64),
    radius: impl Fn(f64) -> f64,
) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let mut v = Vec::with_capacity(around * rows);
    for j in 0..rows {
        let h = y.0 + (y.1 - y.0) * j as f64 / (rows - 1) as f64;
        for i in 0..around {
            let t = std::f64::consts::TAU * i as f64 / around as f64;
            v.push([radius(h) * t.cos(), h, radius(h) * t.sin()]);
        }
    }
    let mut f = Vec::with_capacity(2 * around * (rows - 1));
    for j in 0..rows - 1 {
        for i in 0..around {
            let a = (j * around + i) as u32;
            let b = (j * around + (i + 1) % around) as u32;
            let (c, d) = (a + around as u32, b + around as u32);
            f.push([a, b, d]);
            f.push([a, d, c]);
        }
    }
    (v, f)
}

/// `count` points uniformly distributed over the surface of a triangle mesh (area-weighted face
/// choice, uniform barycentric coordinates).
pub fn sample_surface(
    vertices: &[[f64; 3]],
    faces: &[[u32; 3]],
    count: usize,
    rng: &mut SplitMix64,
) -> Vec<[f64; 3]> {
    let mut cumulative = Vec::with_capacity(faces.len());
    let mut total = 0.0;
    for f in faces {
        total += crate::mesh::face_area_normal(vertices, f).norm();
        cumulative.push(total);
    }
    (0..count)
        .map(|_| {
            let target = rng.uniform() * total;
            let fi = cumulative
                .partition_point(|&c| c < target)
                .min(faces.len() - 1);
            let f = faces[fi];
            let (mut a, mut b) = (rng.uniform(), rng.uniform());
            if a + b > 1.0 {
                a = 1.0 - a;
                b = 1.0 - b;
            }
            let (p0, p1, p2) = (
                vec3(&vertices[f[0] as usize]),
                vec3(&vertices[f[1] as usize]),
                vec3(&vertices[f[2] as usize]),
            );
            (p0 + a * (p1 - p0) + b * (p2 - p0)).into()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sheet_and_scan_are_deterministic_and_sized() {
        let spec = SheetSpec {
            scan_points: 500,
            noise: 0.001,
            ..Default::default()
        };
        let a = folded_sheet(&spec);
        let b = folded_sheet(&spec);
        assert_eq!(a.scan, b.scan);
        assert_eq!(a.template_vertices.len(), 41 * 41);
        assert_eq!(a.faces.len(), 2 * 40 * 40);
        assert_eq!(a.scan.len(), 500);
        assert_eq!(a.ground_truth.len(), a.template_vertices.len());
    }
}
