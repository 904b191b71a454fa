//! Local contact frames.

use nalgebra::Vector3;

/// The local frame `[n, t, s]` of a contact with unit normal `n`: `t` and `s` unit,
/// orthogonal, right-handed (`n × t = s`). A deterministic function of `n` (the
/// branch-free construction of Duff et al. 2017), so a contact whose normal does not
/// change keeps its tangents and its warm-start impulse stays meaningful.
pub fn local_frame(n: &Vector3<f64>) -> [Vector3<f64>; 3] {
    let sign = 1f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let t = Vector3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let s = Vector3::new(b, sign + n.y * n.y * a, -n.y);
    [*n, t, s]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_orthonormal_and_right_handed() {
        for n in [
            Vector3::new(0.0, 0.0, 1.0),
            Vector3::new(0.0, 0.0, -1.0),
            Vector3::new(1.0, 2.0, -3.0).normalize(),
            Vector3::new(-0.3, 0.1, 0.2).normalize(),
            Vector3::new(1.0, 0.0, 0.0),
        ] {
            let [n, t, s] = local_frame(&n);
            assert!((t.norm() - 1.0).abs() < 1e-14);
            assert!((s.norm() - 1.0).abs() < 1e-14);
            assert!(n.dot(&t).abs() < 1e-14 && n.dot(&s).abs() < 1e-14 && t.dot(&s).abs() < 1e-14);
            assert!((n.cross(&t) - s).norm() < 1e-14);
        }
    }
}
