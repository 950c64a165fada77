//! Views and the orthographic camera of the preview: the model turned about its vertical axis
//! (+y up, the OBJ/PLY convention of scanners and garment templates) and scaled so that its
//! bounding sphere fills a panel, the same scale in every view and row.

/// A direction the model is seen from: a turn about the vertical (+y) axis, the camera on +z.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum View {
    /// Seen from +z (no turn).
    Front,
    /// Turned 45° about +y.
    ThreeQuarter,
    /// Turned 90° about +y (seen from −x).
    Side,
    /// Turned 180° about +y (seen from −z).
    Back,
}

impl View {
    /// The views of a preview unless told otherwise: front, three-quarter and back.
    pub const DEFAULT: [View; 3] = [View::Front, View::ThreeQuarter, View::Back];

    /// The turn about +y, in degrees.
    pub fn yaw_degrees(self) -> f64 {
        match self {
            View::Front => 0.0,
            View::ThreeQuarter => 45.0,
            View::Side => 90.0,
            View::Back => 180.0,
        }
    }

    /// The name used on the command line and in Python (`front`, `three-quarter`, `side`,
    /// `back`).
    pub fn name(self) -> &'static str {
        match self {
            View::Front => "front",
            View::ThreeQuarter => "three-quarter",
            View::Side => "side",
            View::Back => "back",
        }
    }

    /// The view called `name` (see [`View::name`]; any case), if any.
    pub fn from_name(name: &str) -> Option<View> {
        [View::Front, View::ThreeQuarter, View::Side, View::Back]
            .into_iter()
            .find(|v| v.name().eq_ignore_ascii_case(name.trim()))
    }
}

/// The sphere every panel frames: the center and half-diagonal of the bounding box of all the
/// points drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Bounds {
    pub center: [f64; 3],
    pub radius: f64,
}

impl Bounds {
    /// The bounds of the finite points of every set (a unit sphere at the origin when none).
    pub fn of(sets: &[&[[f64; 3]]]) -> Self {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in sets.iter().flat_map(|s| s.iter()) {
            if p.iter().all(|c| c.is_finite()) {
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
        }
        if lo[0] > hi[0] {
            return Self {
                center: [0.0; 3],
                radius: 1.0,
            };
        }
        let center = [0, 1, 2].map(|k| 0.5 * (lo[k] + hi[k]));
        let radius = 0.5 * (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt();
        Self {
            center,
            radius: if radius > 0.0 { radius } else { 1.0 },
        }
    }
}

/// Orthographic projection of one view onto a square panel of `size` pixels.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Camera {
    center: [f64; 3],
    cos: f64,
    sin: f64,
    scale: f64,
    half: f64,
}

impl Camera {
    /// The camera of `view` framing `bounds` in a panel of `size` pixels (the sphere's
    /// diameter spans 92 % of the panel, whatever the turn).
    pub fn new(bounds: &Bounds, view: View, size: u32) -> Self {
        let yaw = view.yaw_degrees().to_radians();
        let half = 0.5 * f64::from(size);
        Self {
            center: bounds.center,
            cos: yaw.cos(),
            sin: yaw.sin(),
            scale: 0.92 * half / bounds.radius,
            half,
        }
    }

    /// `v` turned into the camera's frame (x right, y up, z toward the viewer).
    pub fn turn(&self, v: [f64; 3]) -> [f64; 3] {
        [
            self.cos * v[0] + self.sin * v[2],
            v[1],
            -self.sin * v[0] + self.cos * v[2],
        ]
    }

    /// Pixel coordinates of `p` (x right, y down, from the panel's top-left corner) and its
    /// depth (larger is nearer the viewer, in model units from the center).
    pub fn project(&self, p: &[f64; 3]) -> [f32; 3] {
        let q = self.turn([0, 1, 2].map(|k| p[k] - self.center[k]));
        [
            (self.half + self.scale * q[0]) as f32,
            (self.half - self.scale * q[1]) as f32,
            q[2] as f32,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_turn_about_the_vertical_axis() {
        let b = Bounds {
            center: [0.0; 3],
            radius: 1.0,
        };
        let p = [1.0, 0.5, 0.0];
        let front = Camera::new(&b, View::Front, 100).project(&p);
        let back = Camera::new(&b, View::Back, 100).project(&p);
        let side = Camera::new(&b, View::Side, 100).project(&p);
        // +x is right from the front, left from the back, and toward −depth from the side.
        assert!(front[0] > 50.0 && back[0] < 50.0);
        assert!((front[0] - 50.0 + (back[0] - 50.0)).abs() < 1e-4);
        assert!((side[0] - 50.0).abs() < 1e-4 && side[2] < 0.0);
        // +y is up (smaller pixel row) in every view.
        for cam in [front, back, side] {
            assert!((cam[1] - (50.0 - 46.0 * 0.5)).abs() < 1e-4);
        }
        for v in [View::Front, View::ThreeQuarter, View::Side, View::Back] {
            assert_eq!(View::from_name(v.name()), Some(v));
        }
        assert_eq!(View::from_name("up"), None);
    }

    #[test]
    fn bounds_frame_every_set_and_skip_non_finite_points() {
        let a = [[0.0, 0.0, 0.0], [f64::NAN, 0.0, 0.0]];
        let b = [[2.0, 0.0, 0.0]];
        let bounds = Bounds::of(&[&a, &b]);
        assert_eq!(bounds.center, [1.0, 0.0, 0.0]);
        assert_eq!(bounds.radius, 1.0);
        assert_eq!(Bounds::of(&[]).radius, 1.0);
    }
}
