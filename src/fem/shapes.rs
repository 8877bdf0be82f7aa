//! Shape functions, their reference derivatives and Gauss rules per cell kind (gmsh node
//! order), and the 1-D edge functions for boundary loads.

use crate::mesh::CellKind;

/// Shape function values N_a and their reference derivatives (∂N_a/∂ξ, ∂N_a/∂η) at a point.
type Shape = (Vec<f64>, Vec<[f64; 2]>);

/// Shape function values N_a and reference derivatives (∂N_a/∂ξ, ∂N_a/∂η) at (ξ, η).
pub fn shape(kind: CellKind, xi: f64, eta: f64) -> (Vec<f64>, Vec<[f64; 2]>) {
    match kind {
        CellKind::Tri3 => tri3(xi, eta),
        CellKind::Tri6 => tri6(xi, eta),
        CellKind::Quad4 => quad4(xi, eta),
        CellKind::Quad8 => quad8(xi, eta),
        CellKind::Quad9 => quad9(xi, eta),
    }
}

/// The linear triangle: N = (1 − ξ − η, ξ, η).
fn tri3(xi: f64, eta: f64) -> Shape {
    let n = vec![1.0 - xi - eta, xi, eta];
    let d = vec![[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]];
    (n, d)
}

/// The quadratic triangle in area coordinates l0 = 1 − ξ − η, l1 = ξ, l2 = η: corners
/// l_a (2 l_a − 1), mid-edge nodes 4 l_a l_b.
fn tri6(xi: f64, eta: f64) -> Shape {
    let l0 = 1.0 - xi - eta;
    let (l1, l2) = (xi, eta);
    let n = vec![
        l0 * (2.0 * l0 - 1.0),
        l1 * (2.0 * l1 - 1.0),
        l2 * (2.0 * l2 - 1.0),
        4.0 * l0 * l1,
        4.0 * l1 * l2,
        4.0 * l2 * l0,
    ];
    // dl0 = (−1, −1), dl1 = (1, 0), dl2 = (0, 1)
    let d = vec![
        [-(4.0 * l0 - 1.0), -(4.0 * l0 - 1.0)],
        [4.0 * l1 - 1.0, 0.0],
        [0.0, 4.0 * l2 - 1.0],
        [4.0 * (l0 - l1), -4.0 * l1],
        [4.0 * l2, 4.0 * l1],
        [-4.0 * l2, 4.0 * (l0 - l2)],
    ];
    (n, d)
}

/// The bilinear quadrilateral: N_a = ¼ (1 + ξ_a ξ)(1 + η_a η) at the corners (ξ_a, η_a).
fn quad4(xi: f64, eta: f64) -> Shape {
    let s = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
    let n = s
        .iter()
        .map(|c| 0.25 * (1.0 + c[0] * xi) * (1.0 + c[1] * eta))
        .collect();
    let d = s
        .iter()
        .map(|c| {
            [
                0.25 * c[0] * (1.0 + c[1] * eta),
                0.25 * c[1] * (1.0 + c[0] * xi),
            ]
        })
        .collect();
    (n, d)
}

/// The serendipity quadrilateral: corners ¼ (1 + ξ_a ξ)(1 + η_a η)(ξ_a ξ + η_a η − 1),
/// mid-edge nodes ½ (1 − ξ²)(1 + η_a η) or ½ (1 + ξ_a ξ)(1 − η²).
fn quad8(xi: f64, eta: f64) -> Shape {
    let corners = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
    let mids = [[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]];
    let mut n = Vec::with_capacity(8);
    let mut d = Vec::with_capacity(8);
    for c in corners {
        let (a, b) = (1.0 + c[0] * xi, 1.0 + c[1] * eta);
        let s = c[0] * xi + c[1] * eta - 1.0;
        n.push(0.25 * a * b * s);
        d.push([0.25 * c[0] * b * (s + a), 0.25 * c[1] * a * (s + b)]);
    }
    for m in mids {
        if m[0] == 0.0 {
            n.push(0.5 * (1.0 - xi * xi) * (1.0 + m[1] * eta));
            d.push([-xi * (1.0 + m[1] * eta), 0.5 * (1.0 - xi * xi) * m[1]]);
        } else {
            n.push(0.5 * (1.0 + m[0] * xi) * (1.0 - eta * eta));
            d.push([0.5 * m[0] * (1.0 - eta * eta), -(1.0 + m[0] * xi) * eta]);
        }
    }
    (n, d)
}

/// The biquadratic (Lagrange) quadrilateral: products of the 1-D quadratics on −1, 0, 1.
fn quad9(xi: f64, eta: f64) -> Shape {
    // Tensor product of 1-D quadratics on nodes −1, 0, 1.
    let q = |t: f64| [0.5 * t * (t - 1.0), 1.0 - t * t, 0.5 * t * (t + 1.0)];
    let dq = |t: f64| [t - 0.5, -2.0 * t, t + 0.5];
    // gmsh order: corners (−1,−1) (1,−1) (1,1) (−1,1), mids (0,−1) (1,0) (0,1) (−1,0), centre.
    let idx = [
        [0, 0],
        [2, 0],
        [2, 2],
        [0, 2],
        [1, 0],
        [2, 1],
        [1, 2],
        [0, 1],
        [1, 1],
    ];
    let (qx, qy, dx, dy) = (q(xi), q(eta), dq(xi), dq(eta));
    let n = idx.iter().map(|[i, j]| qx[*i] * qy[*j]).collect();
    let d = idx
        .iter()
        .map(|[i, j]| [dx[*i] * qy[*j], qx[*i] * dy[*j]])
        .collect();
    (n, d)
}

/// Gauss points (ξ, η, weight) exact to polynomial degree `degree` (≤ 5 for triangles).
pub fn gauss(kind: CellKind, degree: usize) -> Vec<(f64, f64, f64)> {
    match kind {
        CellKind::Tri3 | CellKind::Tri6 => {
            if degree <= 1 {
                vec![(1.0 / 3.0, 1.0 / 3.0, 0.5)]
            } else if degree == 2 {
                let w = 1.0 / 6.0;
                vec![
                    (1.0 / 6.0, 1.0 / 6.0, w),
                    (2.0 / 3.0, 1.0 / 6.0, w),
                    (1.0 / 6.0, 2.0 / 3.0, w),
                ]
            } else {
                // 7-point Radon rule, degree 5 (weights for the reference area 1/2).
                let a1 = 0.059_715_871_789_769_82;
                let b1 = 0.470_142_064_105_115_1;
                let a2 = 0.797_426_985_353_087_3;
                let b2 = 0.101_286_507_323_456_3;
                let w0 = 0.225 / 2.0;
                let w1 = 0.132_394_152_788_506_2 / 2.0;
                let w2 = 0.125_939_180_544_827_2 / 2.0;
                vec![
                    (1.0 / 3.0, 1.0 / 3.0, w0),
                    (a1, b1, w1),
                    (b1, a1, w1),
                    (b1, b1, w1),
                    (a2, b2, w2),
                    (b2, a2, w2),
                    (b2, b2, w2),
                ]
            }
        }
        CellKind::Quad4 | CellKind::Quad8 | CellKind::Quad9 => {
            let line = gauss_line(degree);
            let mut pts = Vec::with_capacity(line.len() * line.len());
            for &(x, wx) in &line {
                for &(y, wy) in &line {
                    pts.push((x, y, wx * wy));
                }
            }
            pts
        }
    }
}

/// Gauss–Legendre points on [−1, 1] exact to `degree`.
pub fn gauss_line(degree: usize) -> Vec<(f64, f64)> {
    if degree <= 1 {
        vec![(0.0, 2.0)]
    } else if degree <= 3 {
        let a = 1.0 / 3f64.sqrt();
        vec![(-a, 1.0), (a, 1.0)]
    } else if degree <= 5 {
        let a = (0.6f64).sqrt();
        vec![(-a, 5.0 / 9.0), (0.0, 8.0 / 9.0), (a, 5.0 / 9.0)]
    } else {
        let (a, b) = (0.339_981_043_584_856_3, 0.861_136_311_594_052_6);
        let (wa, wb) = (0.652_145_154_862_546_1, 0.347_854_845_137_453_9);
        vec![(-b, wb), (-a, wa), (a, wa), (b, wb)]
    }
}

/// 1-D edge shape functions on [−1, 1] in gmsh line order: 2 nodes (end, end) or 3 nodes
/// (end, end, middle); values and d/dt.
pub fn edge_shape(nodes: usize, t: f64) -> (Vec<f64>, Vec<f64>) {
    if nodes == 2 {
        (vec![0.5 * (1.0 - t), 0.5 * (1.0 + t)], vec![-0.5, 0.5])
    } else {
        (
            vec![0.5 * t * (t - 1.0), 0.5 * t * (t + 1.0), 1.0 - t * t],
            vec![t - 0.5, t + 0.5, -2.0 * t],
        )
    }
}
