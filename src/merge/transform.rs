//! Rigid transforms between two maps' pixel frames: `p_a = R(theta) p_b + t`, x right, y down, pixel centres
//! at integers, `R = [[cos, -sin], [sin, cos]]` (a positive angle turns clockwise on screen, since y points
//! down).

use serde::Serialize;

use crate::map::GeoRef;

/// A rigid transform from map B's pixel coordinates to map A's.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Rigid {
    /// Rotation, degrees.
    pub theta_deg: f64,
    /// Translation along x, pixels.
    pub tx: f64,
    /// Translation along y, pixels.
    pub ty: f64,
}

/// A [`Rigid`] ready to map many points: its rotation's cosine and sine, and its translation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Applier {
    c: f64,
    s: f64,
    tx: f64,
    ty: f64,
}

impl Applier {
    /// Where point `p` lands ([`Rigid::apply`]).
    #[inline]
    pub fn apply(&self, (x, y): (f64, f64)) -> (f64, f64) {
        (
            self.c * x - self.s * y + self.tx,
            self.s * x + self.c * y + self.ty,
        )
    }
}

impl Rigid {
    /// The identity.
    pub const IDENTITY: Rigid = Rigid {
        theta_deg: 0.0,
        tx: 0.0,
        ty: 0.0,
    };

    /// Where point `p` of B lands in A.
    pub fn apply(&self, p: (f64, f64)) -> (f64, f64) {
        self.applier().apply(p)
    }

    /// [`Rigid::apply`] with the rotation's sine and cosine computed once, for many points (the same
    /// results).
    pub fn applier(&self) -> Applier {
        let (s, c) = self.theta_deg.to_radians().sin_cos();
        Applier {
            c,
            s,
            tx: self.tx,
            ty: self.ty,
        }
    }

    /// The transform from A to B.
    pub fn inverse(&self) -> Rigid {
        let (s, c) = self.theta_deg.to_radians().sin_cos();
        // p_b = R^T (p_a - t)
        Rigid {
            theta_deg: -self.theta_deg,
            tx: -(c * self.tx + s * self.ty),
            ty: -(-s * self.tx + c * self.ty),
        }
    }

    /// `self` after `first`: p -> self(first(p)).
    pub fn after(&self, first: &Rigid) -> Rigid {
        let (tx, ty) = self.apply((first.tx, first.ty));
        Rigid {
            theta_deg: self.theta_deg + first.theta_deg,
            tx,
            ty,
        }
    }

    /// The angle in (-180, 180].
    pub fn normalized(&self) -> Rigid {
        Rigid {
            theta_deg: signed_deg(self.theta_deg),
            ..*self
        }
    }
}

/// The least-squares rigid transform taking each point of `from` to its partner in `to` (closed form;
/// the identity for fewer than two points): ICP's step, and the truth of a bent synthetic pair.
pub fn fit_rigid(from: &[(f64, f64)], to: &[(f64, f64)]) -> Rigid {
    let n = from.len().min(to.len());
    if n < 2 {
        return Rigid::IDENTITY;
    }
    let mean = |v: &[(f64, f64)]| {
        let s = v[..n]
            .iter()
            .fold((0.0, 0.0), |a, p| (a.0 + p.0, a.1 + p.1));
        (s.0 / n as f64, s.1 / n as f64)
    };
    let (mp, mq) = (mean(from), mean(to));
    let (mut sxx, mut sxy) = (0.0, 0.0);
    for (p, q) in from.iter().zip(to).take(n) {
        let (px, py, qx, qy) = (p.0 - mp.0, p.1 - mp.1, q.0 - mq.0, q.1 - mq.1);
        sxx += px * qx + py * qy;
        sxy += px * qy - py * qx;
    }
    // Through degrees, as every transform here is kept: ICP's iterations stop on these exact values.
    let theta = sxy.atan2(sxx).to_degrees();
    let (s, c) = theta.to_radians().sin_cos();
    Rigid {
        theta_deg: theta,
        tx: mq.0 - (c * mp.0 - s * mp.1),
        ty: mq.1 - (s * mp.0 + c * mp.1),
    }
}

/// A transform in A's map frame (metres, radians; x east, y north as ROS has it): the pose of B's map
/// frame in A's, `w_a = R(yaw) w_b + (x, y)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct WorldRigid {
    /// Rotation, radians (counter-clockwise, as ROS yaw).
    pub yaw: f64,
    /// Translation, metres.
    pub x: f64,
    /// Translation, metres.
    pub y: f64,
}

impl std::fmt::Display for WorldRigid {
    /// `yaw deg, (x, y) m`, as the verdicts print it.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{:.2} deg, ({:.3}, {:.3}) m",
            self.yaw.to_degrees(),
            self.x,
            self.y
        )
    }
}

/// The world form of a pixel transform between two georeferenced maps of heights `ha` and `hb`: maps a
/// world point of B's frame to A's frame. Pixel rows count down and world y up, so the pixel angle flips
/// sign; both maps' yaws are taken into account through their pixel-to-world functions.
pub fn to_world(t: &Rigid, a: &GeoRef, ha: u32, b: &GeoRef, hb: u32) -> WorldRigid {
    // Two points of B: their world positions in B's frame and, through the transform, in A's frame.
    let world_a = |p: (f64, f64)| a.point_to_world(p, ha);
    let world_b = |p: (f64, f64)| b.point_to_world(p, hb);
    let (p0, p1) = ((0.0, 0.0), (1000.0, 0.0));
    let (wb0, wb1) = (world_b(p0), world_b(p1));
    let (wa0, wa1) = (world_a(t.apply(p0)), world_a(t.apply(p1)));
    let yaw = (wa1.1 - wa0.1).atan2(wa1.0 - wa0.0) - (wb1.1 - wb0.1).atan2(wb1.0 - wb0.0);
    let yaw =
        (yaw + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI;
    let (s, c) = yaw.sin_cos();
    WorldRigid {
        yaw,
        x: wa0.0 - (c * wb0.0 - s * wb0.1),
        y: wa0.1 - (s * wb0.0 + c * wb0.1),
    }
}

/// An angle in degrees brought into (-180, 180].
pub fn signed_deg(deg: f64) -> f64 {
    let t = deg.rem_euclid(360.0);
    if t > 180.0 {
        t - 360.0
    } else {
        t
    }
}

/// Two candidates are distinct when they move B's reference points (wall bounding box corners and
/// centroid) by more than this RMS, pixels; two poses when [`transform_distance`] says so.
pub(super) const DISTINCT_PX: f64 = 40.0;

/// How far apart two transforms are: their translations' distance plus 10 px a degree of turn.
pub(super) fn transform_distance(x: &Rigid, y: &Rigid) -> f64 {
    (x.tx - y.tx).hypot(x.ty - y.ty) + 10.0 * signed_deg(x.theta_deg - y.theta_deg).abs()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_and_composition_round_trip() {
        let t = Rigid {
            theta_deg: 33.0,
            tx: 12.5,
            ty: -40.0,
        };
        let p = (17.0, 5.0);
        let q = t.apply(p);
        let back = t.inverse().apply(q);
        assert!((back.0 - p.0).abs() < 1e-9 && (back.1 - p.1).abs() < 1e-9);
        let u = Rigid {
            theta_deg: -80.0,
            tx: 3.0,
            ty: 7.0,
        };
        let both = u.after(&t).apply(p);
        let step = u.apply(t.apply(p));
        assert!((both.0 - step.0).abs() < 1e-9 && (both.1 - step.1).abs() < 1e-9);
        assert_eq!(
            Rigid {
                theta_deg: 270.0,
                ..t
            }
            .normalized()
            .theta_deg,
            -90.0
        );
    }

    #[test]
    fn world_form_maps_world_points_of_b_onto_a() {
        let a = GeoRef {
            resolution: 0.05,
            origin: [-10.0, -5.0, 0.0],
        };
        let b = GeoRef {
            resolution: 0.05,
            origin: [2.0, 1.0, 0.0],
        };
        let t = Rigid {
            theta_deg: 20.0,
            tx: 30.0,
            ty: -12.0,
        };
        let w = to_world(&t, &a, 400, &b, 300);
        for p in [(10.0, 20.0), (150.0, 80.0)] {
            let wb = b.point_to_world(p, 300);
            let wa = a.point_to_world(t.apply(p), 400);
            let (s, c) = w.yaw.sin_cos();
            let got = (c * wb.0 - s * wb.1 + w.x, s * wb.0 + c * wb.1 + w.y);
            assert!(
                (got.0 - wa.0).abs() < 1e-9 && (got.1 - wa.1).abs() < 1e-9,
                "{got:?} {wa:?}"
            );
        }
        // Rows count down and world y up: a pixel angle of +20 degrees is a world yaw of -20 degrees.
        assert!((w.yaw.to_degrees() + 20.0).abs() < 1e-9);
    }
}
