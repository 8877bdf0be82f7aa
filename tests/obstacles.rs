//! The contact candidates against each obstacle kind, on small meshes built by hand (and one
//! meshed by gmsh): unit normals from the body toward the obstacle, gaps equal to the analytic
//! distance (> 0 open, < 0 penetrating), nodes beyond `search_distance` or off the obstacle
//! dropped and counted, and bad contact input refused naming the group.
//!
//! Reference for the gap and normal definitions: Wriggers, Computational Contact Mechanics,
//! §4.1 (the normal gap g_N = (x̄ − x)·n̄ of a node x to its closest obstacle point x̄).

mod common;

use std::collections::BTreeMap;

use hbcontact::contact::geometry::{build_contact_set, ContactScene, ContactSet, Obstacle};
use hbcontact::mesh::{Cell, CellKind, Edge, Mesh2d};

/// A strip of Quad4 cells over the bottom nodes `bottom` (x, y), with a flat top at y = `top`.
/// Groups: `body` (cells), `bottom` (the bottom edges), `right` (the right face), `left`,
/// `corner` (a point: the bottom-left node).
fn strip(bottom: &[[f64; 2]], top: f64) -> Mesh2d {
    let n = bottom.len();
    let mut mesh = Mesh2d::default();
    mesh.nodes.extend_from_slice(bottom);
    mesh.nodes.extend(bottom.iter().map(|p| [p[0], top]));
    for i in 0..n - 1 {
        mesh.cells.push(Cell {
            kind: CellKind::Quad4,
            nodes: vec![i, i + 1, n + i + 1, n + i],
        });
    }
    mesh.cell_groups
        .insert("body".into(), (0..n - 1).collect::<Vec<_>>());
    let edges = |pairs: Vec<[usize; 2]>| -> Vec<Edge> {
        pairs
            .into_iter()
            .map(|p| Edge { nodes: p.to_vec() })
            .collect()
    };
    mesh.edge_groups.insert(
        "bottom".into(),
        edges((0..n - 1).map(|i| [i, i + 1]).collect()),
    );
    mesh.edge_groups
        .insert("right".into(), edges(vec![[n - 1, 2 * n - 1]]));
    mesh.edge_groups.insert("left".into(), edges(vec![[0, n]]));
    mesh.node_groups
        .insert("body".into(), (0..2 * n).collect::<Vec<_>>());
    mesh.node_groups
        .insert("bottom".into(), (0..n).collect::<Vec<_>>());
    mesh.node_groups
        .insert("right".into(), vec![n - 1, 2 * n - 1]);
    mesh.node_groups.insert("left".into(), vec![0, n]);
    mesh.node_groups.insert("corner".into(), vec![0]);
    mesh
}

/// The unit square [0, 1]² as a 4 × 4 grid of Quad4 cells; group `rim` = its whole boundary
/// (16 nodes), `right` = the face x = 1 (5 nodes at y = 0, 0.25, …, 1).
fn square() -> Mesh2d {
    let idx = |i: usize, j: usize| j * 5 + i;
    let mut mesh = Mesh2d::default();
    for j in 0..5 {
        for i in 0..5 {
            mesh.nodes.push([0.25 * i as f64, 0.25 * j as f64]);
        }
    }
    for j in 0..4 {
        for i in 0..4 {
            mesh.cells.push(Cell {
                kind: CellKind::Quad4,
                nodes: vec![idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)],
            });
        }
    }
    mesh.cell_groups.insert("body".into(), (0..16).collect());
    mesh.node_groups.insert("body".into(), (0..25).collect());
    let mut rim = Vec::new();
    for i in 0..4 {
        rim.push([idx(i, 0), idx(i + 1, 0)]);
        rim.push([idx(4, i), idx(4, i + 1)]);
        rim.push([idx(i + 1, 4), idx(i, 4)]);
        rim.push([idx(0, i + 1), idx(0, i)]);
    }
    let right: Vec<[usize; 2]> = (0..4).map(|j| [idx(4, j), idx(4, j + 1)]).collect();
    for (name, pairs) in [("rim", rim), ("right", right)] {
        let mut nodes: Vec<usize> = pairs.iter().flatten().copied().collect();
        nodes.sort_unstable();
        nodes.dedup();
        mesh.node_groups.insert(name.into(), nodes);
        mesh.edge_groups.insert(
            name.into(),
            pairs
                .into_iter()
                .map(|p| Edge { nodes: p.to_vec() })
                .collect(),
        );
    }
    mesh
}

/// Append a polyline of 2-node edges as a curve group carrying no cells (an obstacle).
fn add_curve(mesh: &mut Mesh2d, name: &str, points: &[[f64; 2]]) {
    let first = mesh.nodes.len();
    mesh.nodes.extend_from_slice(points);
    let ids: Vec<usize> = (first..first + points.len()).collect();
    mesh.edge_groups.insert(
        name.into(),
        ids.windows(2).map(|w| Edge { nodes: w.to_vec() }).collect(),
    );
    mesh.node_groups.insert(name.into(), ids);
}

fn spec(boundary: &str, obstacle: Obstacle, search: Option<f64>) -> ContactScene {
    ContactScene {
        boundary: boundary.into(),
        obstacle,
        search_distance: search,
    }
}

fn norm(v: [f64; 2]) -> f64 {
    (v[0] * v[0] + v[1] * v[1]).sqrt()
}

/// What every contact set must satisfy whatever the obstacle: unit normals, the closest point
/// at gap·n from the node, and one entry per kept node.
fn check_consistent(mesh: &Mesh2d, set: &ContactSet) {
    let k = set.nodes.len();
    assert!(k > 0);
    assert_eq!(set.normals.len(), k);
    assert_eq!(set.gaps.len(), k);
    assert_eq!(set.closest.len(), k);
    assert_eq!(set.tributary.len(), k);
    assert!(set.nodes.windows(2).all(|w| w[0] < w[1]), "sorted");
    assert_eq!(
        k + set.dropped_off_obstacle + set.dropped_beyond_search,
        set.candidates,
        "every candidate is kept or counted as dropped"
    );
    for (i, &n) in set.nodes.iter().enumerate() {
        let (x, nrm, g, c) = (mesh.nodes[n], set.normals[i], set.gaps[i], set.closest[i]);
        assert!(
            (norm(nrm) - 1.0).abs() < 1e-14,
            "node {n}: |n| = {}",
            norm(nrm)
        );
        assert!(
            (c[0] - x[0] - g * nrm[0]).abs() < 1e-14 && (c[1] - x[1] - g * nrm[1]).abs() < 1e-14,
            "node {n}: the closest point {c:?} is not x + g n ({x:?} + {g} {nrm:?})"
        );
    }
}

/// TEST GOAL: against an analytic line (the half-plane behind it), the gap is the signed
/// distance of the node to the line (> 0 open, < 0 penetrating), the normal is the unit vector
/// from the body into the obstacle (minus the line's normal, which points toward the body),
/// and nodes farther than `search_distance` are dropped and counted.
///
/// ```text
///   ┌───┬───┬───┬───┐
///   │   │   │   │   │      body: 4 quads, bottom nodes at y = 0.3, 0.1, −0.1, 0.2, 0.6
///   └─╲─┴───┴─╱─┴──╱┘
///  ─────────────────────   obstacle: the line through (0, 0), normal (0.1, 1)/|·| (tilted),
///  ///// obstacle //////   search_distance 0.4 drops the node at x = 1 (gap 0.70)
/// ```
#[test]
fn line_obstacle_gaps_are_signed_distances_and_normals_point_into_it() {
    let bottom = [
        [0.0, 0.3],
        [0.25, 0.1],
        [0.5, -0.1],
        [0.75, 0.2],
        [1.0, 0.6],
    ];
    let mesh = strip(&bottom, 2.0);
    let l = norm([0.1, 1.0]);
    let n_line = [0.1 / l, 1.0 / l];
    let point = [0.0, 0.0];
    let obstacle = Obstacle::Line {
        point,
        normal: n_line,
    };
    let distance = |x: [f64; 2]| (x[0] - point[0]) * n_line[0] + (x[1] - point[1]) * n_line[1];

    let all = build_contact_set(&mesh, &spec("bottom", obstacle.clone(), None)).unwrap();
    check_consistent(&mesh, &all);
    assert_eq!(all.nodes, vec![0, 1, 2, 3, 4]);
    for (i, &n) in all.nodes.iter().enumerate() {
        let x = mesh.nodes[n];
        assert!(
            (all.gaps[i] - distance(x)).abs() < 1e-15,
            "node {n}: gap {} vs signed distance {}",
            all.gaps[i],
            distance(x)
        );
        assert_eq!(all.normals[i], [-n_line[0], -n_line[1]]);
        // From the body: the normal points away from the body's interior (downward here).
        assert!(all.normals[i][1] < 0.0);
    }
    // Sign convention: the node below the line penetrates, the others are open.
    println!("line gaps: {:?}", all.gaps);
    assert!(all.gaps[2] < 0.0, "x = (0.5, −0.1) is inside the obstacle");
    assert!(all.gaps.iter().enumerate().all(|(i, &g)| i == 2 || g > 0.0));

    let near = build_contact_set(&mesh, &spec("bottom", obstacle, Some(0.4))).unwrap();
    check_consistent(&mesh, &near);
    assert_eq!(near.nodes, vec![0, 1, 2, 3], "gap(1.0, 0.6) ≈ 0.70 > 0.4");
    assert_eq!(near.dropped_beyond_search, 1);
    assert_eq!(near.dropped_off_obstacle, 0);
    assert_eq!(near.candidates, 5);
}

/// TEST GOAL: a circle obstacle around the body (a casing, `body_inside: true`): the gap is
/// the radius minus the node's distance to the centre, the normal the outward radial unit
/// vector; nodes beyond `search_distance` are dropped and counted; a radius smaller than the
/// corner distance makes the corners penetrate (g < 0).
///
/// ```text
///        .-‾‾‾‾‾-.          casing: centre (0.5, 0.5), radius R
///      /  ┌─────┐  \        body: the unit square (4 × 4 quads), contact boundary = rim
///     |   │     │   |       corners at 0.707 from the centre, edge midpoints at 0.5
///      \  └─────┘  /
///        `-.....-´
/// ```
#[test]
fn circle_casing_gap_is_radius_minus_distance_and_normals_point_outward() {
    let mesh = square();
    let center = [0.5, 0.5];
    let casing = |radius: f64| Obstacle::Circle {
        center,
        radius,
        body_inside: true,
    };
    for radius in [0.75, 0.7] {
        let set = build_contact_set(&mesh, &spec("rim", casing(radius), None)).unwrap();
        check_consistent(&mesh, &set);
        assert_eq!(set.nodes.len(), 16);
        for (i, &n) in set.nodes.iter().enumerate() {
            let r = [mesh.nodes[n][0] - center[0], mesh.nodes[n][1] - center[1]];
            let d = norm(r);
            assert!(
                (set.gaps[i] - (radius - d)).abs() < 1e-15,
                "node {n}: gap {} vs R − d = {}",
                set.gaps[i],
                radius - d
            );
            let u = [r[0] / d, r[1] / d];
            assert!((set.normals[i][0] - u[0]).abs() < 1e-15);
            assert!((set.normals[i][1] - u[1]).abs() < 1e-15);
        }
        let corners = set.gaps.iter().filter(|&&g| g < 0.0).count();
        println!(
            "casing R = {radius}: gaps {:.4}..{:.4}, {corners} penetrating",
            set.gaps.iter().copied().fold(f64::INFINITY, f64::min),
            set.gaps.iter().copied().fold(f64::NEG_INFINITY, f64::max)
        );
        // R = 0.75 clears the corners (0.707), R = 0.7 does not: the 4 corners penetrate.
        assert_eq!(corners, if radius == 0.75 { 0 } else { 4 });
    }
    // search 0.1 keeps the corners (gap 0.043) and drops the 8 nodes next to them (distance
    // sqrt(0.5² + 0.25²) = 0.559, gap 0.191) and the 4 edge midpoints (gap 0.25).
    let near = build_contact_set(&mesh, &spec("rim", casing(0.75), Some(0.1))).unwrap();
    check_consistent(&mesh, &near);
    assert_eq!(near.nodes, vec![0, 4, 20, 24]);
    assert_eq!(near.dropped_beyond_search, 12);
    assert_eq!(near.dropped_off_obstacle, 0);
}

/// TEST GOAL: a circle obstacle outside the body (a rigid cylinder, `body_inside: false`): the
/// gap is the node's distance to the centre minus the radius, the normal the unit vector from
/// the node toward the centre.
///
/// ```text
///   ┌───┬───┬───┬───┐       body: 4 quads with a flat bottom at y = 0.1
///   └───┴───┴───┴───┘
///        .-‾‾‾‾‾-.          cylinder: centre (0.5, −1), radius 1.15 (top at y = 0.15)
///      /           \
/// ```
#[test]
fn circle_cylinder_gap_is_distance_minus_radius_and_normals_point_to_the_centre() {
    let bottom: Vec<[f64; 2]> = (0..5).map(|i| [0.25 * i as f64, 0.1]).collect();
    let mesh = strip(&bottom, 1.0);
    let center = [0.5, -1.0];
    let radius = 1.15;
    let obstacle = Obstacle::Circle {
        center,
        radius,
        body_inside: false,
    };
    let set = build_contact_set(&mesh, &spec("bottom", obstacle, None)).unwrap();
    check_consistent(&mesh, &set);
    for (i, &n) in set.nodes.iter().enumerate() {
        let r = [center[0] - mesh.nodes[n][0], center[1] - mesh.nodes[n][1]];
        let d = norm(r);
        assert!((set.gaps[i] - (d - radius)).abs() < 1e-15);
        assert!((set.normals[i][0] - r[0] / d).abs() < 1e-15);
        assert!((set.normals[i][1] - r[1] / d).abs() < 1e-15);
    }
    println!("cylinder gaps: {:?}", set.gaps);
    // Distances to the centre 1.208, 1.128, 1.1, 1.128, 1.208 against R = 1.15: the three
    // middle nodes penetrate, the two outer ones are open.
    assert_eq!(
        set.gaps.iter().map(|&g| g < 0.0).collect::<Vec<_>>(),
        vec![false, true, true, true, false]
    );
}

/// TEST GOAL: a curve obstacle (a group of line elements carrying no cells) shorter than the
/// contact boundary: nodes whose closest obstacle point is a free end of the curve and which
/// do not face it straight across are dropped as "off the obstacle" and counted; the others get
/// the distance to the curve as gap and the curve's unit normal, oriented from the body into
/// the obstacle; an interior vertex of the polyline is not a free end.
///
/// ```text
///   y=1 ┌───────┐ ·        wall: x = 1.1 from y = 0.3 to 1.5 (two collinear segments,
///       │ body  │ |              joined at y = 0.6)
///       │       │ |        right face x = 1: nodes at y = 0, 0.25, 0.5, 0.75, 1
///       │       │ ·  y=0.3 kept: y = 0.5, 0.75, 1 (gap 0.1); dropped: y = 0, 0.25
///   y=0 └───────┘
/// ```
#[test]
fn curve_obstacle_keeps_nodes_facing_it_and_drops_nodes_off_its_ends() {
    let mut mesh = square();
    add_curve(&mut mesh, "wall", &[[1.1, 0.3], [1.1, 0.6], [1.1, 1.5]]);
    let obstacle = Obstacle::Curve {
        group: "wall".into(),
    };
    let set = build_contact_set(&mesh, &spec("right", obstacle.clone(), None)).unwrap();
    check_consistent(&mesh, &set);
    assert_eq!(set.candidates, 5);
    assert_eq!(
        set.dropped_off_obstacle, 2,
        "y = 0 and y = 0.25 miss the wall"
    );
    assert_eq!(set.dropped_beyond_search, 0);
    let ys: Vec<f64> = set.nodes.iter().map(|&n| mesh.nodes[n][1]).collect();
    assert_eq!(ys, vec![0.5, 0.75, 1.0]);
    for i in 0..3 {
        assert!((set.gaps[i] - 0.1).abs() < 1e-15, "gap {}", set.gaps[i]);
        assert_eq!(
            set.normals[i],
            [1.0, 0.0],
            "from the body (x < 1) toward the wall"
        );
    }
    // The same wall pushed into the body: negative gaps, the normal unchanged (it follows the
    // body's outward normal, not the side the node happens to be on).
    let mut pressed = square();
    add_curve(
        &mut pressed,
        "wall",
        &[[0.98, 0.3], [0.98, 0.6], [0.98, 1.5]],
    );
    let set = build_contact_set(&pressed, &spec("right", obstacle.clone(), None)).unwrap();
    check_consistent(&pressed, &set);
    assert!(
        set.gaps.iter().all(|&g| (g + 0.02).abs() < 1e-14),
        "{:?}",
        set.gaps
    );
    assert!(set.normals.iter().all(|&n| n == [1.0, 0.0]));
    // A slanted wall: the gap is the perpendicular distance; search_distance drops the far end.
    let mut slanted = square();
    add_curve(&mut slanted, "wall", &[[1.1, -0.5], [1.6, 1.5]]);
    let t = [0.5 / norm([0.5, 2.0]), 2.0 / norm([0.5, 2.0])];
    let nrm = [t[1], -t[0]]; // points +x, from the body into the wall
    let expected = |x: [f64; 2]| (1.1 - x[0]) * nrm[0] + (-0.5 - x[1]) * nrm[1];
    let set = build_contact_set(&slanted, &spec("right", obstacle, Some(0.25))).unwrap();
    check_consistent(&slanted, &set);
    for (i, &n) in set.nodes.iter().enumerate() {
        assert!((set.gaps[i] - expected(slanted.nodes[n])).abs() < 1e-14);
        assert!((set.normals[i][0] - nrm[0]).abs() < 1e-15);
        assert!((set.normals[i][1] - nrm[1]).abs() < 1e-15);
    }
    println!(
        "slanted wall: gaps {:?}, {} beyond 0.25",
        set.gaps, set.dropped_beyond_search
    );
    // Gaps 0.218, 0.279, 0.339, 0.400, 0.461 at y = 0 … 1: only y = 0 is within 0.25.
    assert_eq!(set.nodes.len(), 1);
    assert_eq!(set.dropped_beyond_search, 4);
}

/// TEST GOAL: a curve obstacle from a gmsh geometry (tests/data/short_wall.geo, order 2, so the
/// wall is meshed as 3-node line elements): a slanted wall covering only the upper part of the
/// body's right face keeps the corners of its quadratic edges facing it, with gaps equal to
/// the mortar average of the distances to the wall's line over each corner's row, and drops
/// the others as off the obstacle.
///
/// ```text
///   y=0.5 ┌──────┐  ╱       body [0, 1] × [0, 0.5], contact boundary `right` (x = 1)
///         │ body │ ╱        wall from (1.05, 0.2) to (1.15, 0.7): faces y ≳ 0.21 only
///   y=0   └──────┘╱·
/// ```
#[test]
fn curve_obstacle_meshed_by_gmsh_matches_the_wall_line() {
    use hbcontact::mesh::gmsh::{mesh_geometry, MeshRequest};
    let request = MeshRequest {
        geo: common::root().join("tests/data/short_wall.geo"),
        parameters: BTreeMap::new(),
        mesh_size: None,
        order: 2,
        quads: false,
        gmsh: None,
        trusted: false,
    };
    let meshed = mesh_geometry(&request, &common::root().join("output/test-mesh-cache"))
        .unwrap_or_else(|e| panic!("{e}"));
    let mesh = hbcontact::mesh::msh::read_msh(&meshed.msh).unwrap_or_else(|e| panic!("{e}"));
    assert!(mesh.edge_groups["wall"].iter().all(|e| e.nodes.len() == 3));
    let set = build_contact_set(
        &mesh,
        &spec(
            "right",
            Obstacle::Curve {
                group: "wall".into(),
            },
            None,
        ),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    check_consistent(&mesh, &set);
    let (a, b) = ([1.05, 0.2], [1.15, 0.7]);
    let t = [
        (b[0] - a[0]) / norm([0.1, 0.5]),
        (b[1] - a[1]) / norm([0.1, 0.5]),
    ];
    let nrm = [t[1], -t[0]];
    let distance = |x: [f64; 2]| (a[0] - x[0]) * nrm[0] + (a[1] - x[1]) * nrm[1];
    for (i, &n) in set.nodes.iter().enumerate() {
        let x = mesh.nodes[n];
        // The law acts on the corners of the quadratic edges, each gap the mortar average of
        // its row's nodes' distances (the weights sum to 1).
        let row: Vec<(usize, f64)> = set.row_nodes(i).collect();
        let total: f64 = row.iter().map(|&(_, w)| w).sum();
        assert!((total - 1.0).abs() < 1e-12, "row weights sum to {total}");
        let expected: f64 = row.iter().map(|&(j, w)| w * distance(mesh.nodes[j])).sum();
        assert!(
            (set.gaps[i] - expected).abs() < 1e-12,
            "node at {x:?}: gap {} vs {expected}",
            set.gaps[i]
        );
        assert!((set.normals[i][0] - nrm[0]).abs() < 1e-12);
        assert!((set.normals[i][1] - nrm[1]).abs() < 1e-12);
        // Faces the wall: the foot of the perpendicular lies within the wall's extent.
        let s = (x[0] - a[0]) * t[0] + (x[1] - a[1]) * t[1];
        assert!(s >= 0.0, "node at {x:?} does not face the wall");
    }
    // The dropped ones are exactly the corners whose perpendicular foot falls before the wall.
    let middles: Vec<usize> = mesh.edge_groups["right"]
        .iter()
        .map(|e| e.nodes[2])
        .collect();
    let right: Vec<usize> = mesh.node_groups["right"]
        .iter()
        .copied()
        .filter(|n| !middles.contains(n))
        .collect();
    let facing = right
        .iter()
        .filter(|&&n| {
            let x = mesh.nodes[n];
            (x[0] - a[0]) * t[0] + (x[1] - a[1]) * t[1] >= 0.0
        })
        .count();
    println!(
        "gmsh wall: {} candidates, {} kept, {} off the obstacle",
        set.candidates,
        set.nodes.len(),
        set.dropped_off_obstacle
    );
    assert_eq!(set.nodes.len(), facing);
    assert!(set.dropped_off_obstacle > 0);
    assert_eq!(set.dropped_off_obstacle, right.len() - facing);
}

/// The error of `build_contact_set` on bad contact input, as (variant name, message).
fn contact_error(mesh: &Mesh2d, spec: &ContactScene) -> (String, String) {
    let e = build_contact_set(mesh, spec).expect_err("bad contact input must be refused");
    // The variant's name is the start of its Debug form ("Model(…)", "Config { … }").
    let debug = format!("{e:?}");
    let class = debug
        .split(|c: char| !c.is_alphanumeric())
        .next()
        .unwrap_or_default()
        .to_string();
    (class, e.to_string())
}

fn bad_inputs() -> Vec<(&'static str, ContactScene, &'static str)> {
    vec![
        (
            "an obstacle curve group with 2-D cells",
            spec(
                "right",
                Obstacle::Curve {
                    group: "body".into(),
                },
                None,
            ),
            "body",
        ),
        (
            "a contact boundary without edges (a point group)",
            spec(
                "corner",
                Obstacle::Line {
                    point: [0.0, -1.0],
                    normal: [0.0, 1.0],
                },
                None,
            ),
            "corner",
        ),
    ]
}

/// TEST GOAL: bad contact input (an obstacle "curve" that is a surface group, a contact
/// boundary that is a point group) is refused with a message naming the group and what it
/// must be.
#[test]
fn bad_contact_input_is_refused_naming_the_group() {
    let mesh = strip(&[[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]], 1.0);
    for (what, spec, group) in bad_inputs() {
        let (class, msg) = contact_error(&mesh, &spec);
        println!("{what}: Error::{class}: {msg}");
        assert!(msg.contains(&format!("`{group}`")), "{what}: {msg}");
    }
    let (_, msg) = contact_error(&mesh, &bad_inputs()[0].1);
    assert!(
        msg.contains("2-D cells") && msg.contains("line elements"),
        "{msg}"
    );
    let (_, msg) = contact_error(&mesh, &bad_inputs()[1].1);
    assert!(msg.contains("no edges") && msg.contains("curve"), "{msg}");
}

/// TEST GOAL: bad contact input is bad input (Error::Input, exit code 2), like every other
/// mistake in the pipeline file, not a model failure (exit code 3).
#[test]
fn bad_contact_input_is_bad_input() {
    let mesh = strip(&[[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]], 1.0);
    for (what, spec, group) in bad_inputs() {
        match build_contact_set(&mesh, &spec) {
            Err(hbcontact::Error::Input(message)) => {
                assert!(message.contains(group), "{what}: {message}")
            }
            Err(e) => panic!("{what}: expected Error::Input, got {e:?}"),
            Ok(_) => panic!("{what}: accepted"),
        }
    }
}
