//! A software z-buffer rasterizer: triangles with per-vertex colors interpolated
//! barycentrically (Gouraud), and square point splats, each pixel kept when it is nearer than
//! what the pixel holds (Foley, van Dam et al., *Computer Graphics: Principles and Practice*,
//! §15.4, the z-buffer algorithm). Sampling is at pixel centers; no antialiasing.

/// An RGB panel with its depth buffer (larger depth is nearer).
pub(crate) struct Canvas {
    pub width: usize,
    pub height: usize,
    pub rgb: Vec<[u8; 3]>,
    depth: Vec<f32>,
}

impl Canvas {
    /// A `width` × `height` canvas filled with `background`, at infinite distance.
    pub fn new(width: usize, height: usize, background: [u8; 3]) -> Self {
        Self {
            width,
            height,
            rgb: vec![background; width * height],
            depth: vec![f32::NEG_INFINITY; width * height],
        }
    }

    /// Draws the triangle of pixel-space corners `p` (x, y, depth) with corner colors `c`.
    pub fn triangle(&mut self, p: [[f32; 3]; 3], c: [[f32; 3]; 3]) {
        if p.iter().flatten().any(|v| !v.is_finite()) {
            return;
        }
        let edge = |a: [f32; 3], b: [f32; 3], x: f32, y: f32| {
            (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0])
        };
        let area = edge(p[0], p[1], p[2][0], p[2][1]);
        if area.abs() < 1e-12 {
            return;
        }
        let (w, h) = (self.width as f32, self.height as f32);
        let min_x = p
            .iter()
            .map(|q| q[0])
            .fold(f32::INFINITY, f32::min)
            .max(0.0);
        let max_x = p
            .iter()
            .map(|q| q[0])
            .fold(f32::NEG_INFINITY, f32::max)
            .min(w - 1.0);
        let min_y = p
            .iter()
            .map(|q| q[1])
            .fold(f32::INFINITY, f32::min)
            .max(0.0);
        let max_y = p
            .iter()
            .map(|q| q[1])
            .fold(f32::NEG_INFINITY, f32::max)
            .min(h - 1.0);
        if min_x > max_x || min_y > max_y {
            return;
        }
        let inv = 1.0 / area;
        for y in (min_y.floor() as usize)..=(max_y.ceil() as usize).min(self.height - 1) {
            let py = y as f32 + 0.5;
            for x in (min_x.floor() as usize)..=(max_x.ceil() as usize).min(self.width - 1) {
                let px = x as f32 + 0.5;
                let b0 = edge(p[1], p[2], px, py) * inv;
                let b1 = edge(p[2], p[0], px, py) * inv;
                let b2 = edge(p[0], p[1], px, py) * inv;
                if b0 < 0.0 || b1 < 0.0 || b2 < 0.0 {
                    continue;
                }
                let z = b0 * p[0][2] + b1 * p[1][2] + b2 * p[2][2];
                let i = y * self.width + x;
                if z <= self.depth[i] {
                    continue;
                }
                self.depth[i] = z;
                self.rgb[i] = [0, 1, 2].map(|k| {
                    (b0 * c[0][k] + b1 * c[1][k] + b2 * c[2][k])
                        .round()
                        .clamp(0.0, 255.0) as u8
                });
            }
        }
    }

    /// Draws a square of side `2·radius + 1` pixels centered on `p` (x, y, depth).
    pub fn point(&mut self, p: [f32; 3], radius: i64, color: [u8; 3]) {
        if !p.iter().all(|v| v.is_finite()) {
            return;
        }
        let (cx, cy) = (p[0].floor() as i64, p[1].floor() as i64);
        for y in (cy - radius)..=(cy + radius) {
            for x in (cx - radius)..=(cx + radius) {
                if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
                    continue;
                }
                let i = y as usize * self.width + x as usize;
                if p[2] > self.depth[i] {
                    self.depth[i] = p[2];
                    self.rgb[i] = color;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearer_triangle_wins_whatever_the_order() {
        let red = [[255.0, 0.0, 0.0]; 3];
        let blue = [[0.0, 0.0, 255.0]; 3];
        let tri = |z: f32| [[0.0, 0.0, z], [10.0, 0.0, z], [0.0, 10.0, z]];
        for order in [[0, 1], [1, 0]] {
            let mut c = Canvas::new(10, 10, [255; 3]);
            let draws = [(tri(1.0), red), (tri(2.0), blue)];
            for k in order {
                c.triangle(draws[k].0, draws[k].1);
            }
            assert_eq!(c.rgb[10 + 1], [0, 0, 255]);
            // Outside the triangle (beyond the hypotenuse) the background stays.
            assert_eq!(c.rgb[9 * 10 + 9], [255; 3]);
        }
    }

    #[test]
    fn colors_are_interpolated_and_winding_does_not_matter() {
        let mut c = Canvas::new(20, 20, [0; 3]);
        let p = [[0.0, 0.0, 0.0], [0.0, 20.0, 0.0], [20.0, 0.0, 0.0]];
        c.triangle(p, [[0.0; 3], [0.0; 3], [200.0, 200.0, 200.0]]);
        // Brightness grows with x (toward the third corner).
        let row = 2 * 20;
        assert!(c.rgb[row + 15][0] > c.rgb[row + 8][0]);
        assert!(c.rgb[row + 8][0] > c.rgb[row + 1][0]);
        let mut degenerate = Canvas::new(4, 4, [7; 3]);
        degenerate.triangle(
            [[0.0; 3], [1.0, 1.0, 0.0], [2.0, 2.0, 0.0]],
            [[255.0; 3]; 3],
        );
        assert!(degenerate.rgb.iter().all(|&p| p == [7; 3]));
    }

    #[test]
    fn points_are_depth_tested_and_clipped() {
        let mut c = Canvas::new(5, 5, [0; 3]);
        c.point([0.5, 0.5, 1.0], 1, [9; 3]);
        c.point([0.5, 0.5, 0.5], 1, [5; 3]);
        assert_eq!(c.rgb[0], [9; 3]);
        assert_eq!(c.rgb[5 + 1], [9; 3]);
        assert_eq!(c.rgb[2 * 5 + 2], [0; 3]);
        c.point([f32::NAN, 0.0, 9.0], 1, [1; 3]);
        assert_eq!(c.rgb[0], [9; 3]);
    }
}
