//! Reading gmsh MSH 4.1 files (ASCII and binary) into `Mesh2d`.
//!
//! mshio parses nodes, elements and entities but skips `$PhysicalNames`, so that section is
//! read here from the raw bytes (it is text even in binary files), and element blocks are
//! mapped to physical groups through their entity's physical tags.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::Path;

use mshio::mshfile::ElementType;

use super::{Cell, CellKind, Edge, Mesh2d};
use crate::{Error, Result};

fn err(path: &Path, message: impl Into<String>) -> Error {
    Error::Mesh {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// (dimension, physical tag) → name, from the `$PhysicalNames` section.
fn physical_names(bytes: &[u8]) -> BTreeMap<(i32, i32), String> {
    let mut names = BTreeMap::new();
    let Some(start) = find(bytes, b"$PhysicalNames") else {
        return names;
    };
    let Some(end) = find(&bytes[start..], b"$EndPhysicalNames") else {
        return names;
    };
    let text = String::from_utf8_lossy(&bytes[start..start + end]);
    for line in text.lines().skip(2) {
        let mut parts = line.trim().splitn(3, char::is_whitespace);
        let (Some(dim), Some(tag), Some(name)) = (parts.next(), parts.next(), parts.next()) else {
            continue;
        };
        if let (Ok(dim), Ok(tag)) = (dim.parse(), tag.parse()) {
            names.insert((dim, tag), name.trim().trim_matches('"').to_string());
        }
    }
    names
}

fn add_nodes(sets: &mut BTreeMap<String, BTreeSet<usize>>, group: &str, nodes: &[usize]) {
    sets.entry(group.to_string())
        .or_default()
        .extend(nodes.iter().copied());
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

fn cell_kind(t: ElementType) -> Option<CellKind> {
    match t {
        ElementType::Tri3 => Some(CellKind::Tri3),
        ElementType::Tri6 => Some(CellKind::Tri6),
        ElementType::Qua4 => Some(CellKind::Quad4),
        ElementType::Qua8 => Some(CellKind::Quad8),
        ElementType::Qua9 => Some(CellKind::Quad9),
        _ => None,
    }
}

/// Twice the signed area of a cell's corner polygon.
fn signed_area2(nodes: &[[f64; 2]], cell: &Cell) -> f64 {
    let k = cell.kind.corners();
    (0..k)
        .map(|a| {
            let p = nodes[cell.nodes[a]];
            let q = nodes[cell.nodes[(a + 1) % k]];
            p[0] * q[1] - q[0] * p[1]
        })
        .sum()
}

/// Reverse a cell's orientation, keeping gmsh's node order conventions (corners, then the
/// mid-edge nodes of edges 0-1, 1-2, …, then the centre).
fn reverse(cell: &mut Cell) {
    let n = &mut cell.nodes;
    match cell.kind {
        // corners 0,2,1; edges (0-2)=old 2-0, (2-1)=old 1-2, (1-0)=old 0-1
        CellKind::Tri3 => n.swap(1, 2),
        CellKind::Tri6 => {
            n.swap(1, 2);
            n.swap(3, 5);
        }
        // corners 0,3,2,1; edges 0-3 (old 3-0), 3-2 (old 2-3), 2-1 (old 1-2), 1-0 (old 0-1)
        CellKind::Quad4 => n.swap(1, 3),
        CellKind::Quad8 | CellKind::Quad9 => {
            n.swap(1, 3);
            n.swap(4, 7);
            n.swap(5, 6);
        }
    }
}

pub fn read_msh(path: &Path) -> Result<Mesh2d> {
    let bytes =
        std::fs::read(path).map_err(|e| err(path, format!("cannot read the mesh file: {e}")))?;
    if !bytes.starts_with(b"$MeshFormat") {
        return Err(err(path, "not a gmsh .msh file (no $MeshFormat header)"));
    }
    let msh = mshio::parse_msh_bytes(&bytes).map_err(|e| {
        let text = format!("{e}");
        let short: String = text.chars().take(600).collect();
        err(
            path,
            format!("cannot parse as MSH 4.1 (write it with gmsh `-format msh41`): {short}"),
        )
    })?;
    let names = physical_names(&bytes);

    // Entity (dim, tag) → physical tags.
    let mut entity_physicals: HashMap<(i32, i32), Vec<i32>> = HashMap::new();
    if let Some(entities) = &msh.data.entities {
        for p in &entities.points {
            entity_physicals.insert((0, p.tag), p.physical_tags.clone());
        }
        for c in &entities.curves {
            entity_physicals.insert((1, c.tag), c.physical_tags.clone());
        }
        for s in &entities.surfaces {
            entity_physicals.insert((2, s.tag), s.physical_tags.clone());
        }
        for v in &entities.volumes {
            entity_physicals.insert((3, v.tag), v.physical_tags.clone());
        }
    }
    let group_name = |dim: i32, tag: i32| {
        names
            .get(&(dim, tag))
            .cloned()
            .unwrap_or_else(|| format!("{dim}D-{tag}"))
    };

    // Nodes, with a tag → index map (tags need not be consecutive).
    let Some(node_data) = &msh.data.nodes else {
        return Err(err(path, "the file has no $Nodes section"));
    };
    let mut nodes = Vec::new();
    let mut node_z = Vec::new();
    let mut index_of: HashMap<u64, usize> = HashMap::new();
    let mut next_tag = node_data.min_node_tag;
    for block in &node_data.node_blocks {
        let mut tags: Vec<(u64, usize)> = match &block.node_tags {
            Some(map) => map.iter().map(|(&t, &i)| (t, i)).collect(),
            // mshio drops contiguous tags: they run on from the previous block.
            None => (0..block.nodes.len())
                .map(|i| (next_tag + i as u64, i))
                .collect(),
        };
        tags.sort_by_key(|&(_, i)| i);
        next_tag += block.nodes.len() as u64;
        for (tag, i) in tags {
            let n = &block.nodes[i];
            index_of.insert(tag, nodes.len());
            node_z.push((tag, n.z, n.x.abs().max(n.y.abs())));
            nodes.push([n.x, n.y]);
        }
    }
    let node_index = |tag: u64| -> Result<usize> {
        index_of.get(&tag).copied().ok_or_else(|| {
            err(
                path,
                format!("an element refers to node {tag}, which is not in $Nodes"),
            )
        })
    };

    let Some(elements) = &msh.data.elements else {
        return Err(err(path, "the file has no $Elements section"));
    };
    let any_physical_2d = elements.element_blocks.iter().any(|b| {
        b.entity_dim == 2
            && entity_physicals
                .get(&(2, b.entity_tag))
                .is_some_and(|p| !p.is_empty())
    });
    let mut mesh = Mesh2d {
        nodes,
        ..Default::default()
    };
    let mut node_sets: BTreeMap<String, BTreeSet<usize>> = BTreeMap::new();
    let mut seen_cells: HashMap<u64, usize> = HashMap::new();
    for block in &elements.element_blocks {
        let physicals = entity_physicals
            .get(&(block.entity_dim, block.entity_tag))
            .cloned()
            .unwrap_or_default();
        let groups: Vec<String> = physicals
            .iter()
            .map(|&t| group_name(block.entity_dim, t))
            .collect();
        match block.entity_dim {
            2 => {
                let Some(kind) = cell_kind(block.element_type) else {
                    return Err(err(
                        path,
                        format!(
                            "unsupported 2-D element type {:?} (gmsh type {}); supported: 3- and 6-node triangles, 4-, 8- and 9-node quadrilaterals (mesh with -order 1 or 2)",
                            block.element_type, block.element_type as u8
                        ),
                    ));
                };
                if physicals.is_empty() && any_physical_2d {
                    continue; // gmsh would not save these either
                }
                for e in &block.elements {
                    let index = match seen_cells.get(&e.element_tag) {
                        Some(&i) => i,
                        None => {
                            let cell_nodes = e
                                .nodes
                                .iter()
                                .map(|&t| node_index(t))
                                .collect::<Result<Vec<_>>>()?;
                            if cell_nodes.len() != kind.nodes_per_cell() {
                                return Err(err(
                                    path,
                                    format!(
                                        "element {} has {} nodes, expected {}",
                                        e.element_tag,
                                        cell_nodes.len(),
                                        kind.nodes_per_cell()
                                    ),
                                ));
                            }
                            mesh.cells.push(Cell {
                                kind,
                                nodes: cell_nodes,
                            });
                            seen_cells.insert(e.element_tag, mesh.cells.len() - 1);
                            mesh.cells.len() - 1
                        }
                    };
                    for g in &groups {
                        mesh.cell_groups.entry(g.clone()).or_default().push(index);
                        node_sets
                            .entry(g.clone())
                            .or_default()
                            .extend(mesh.cells[index].nodes.iter().copied());
                    }
                }
            }
            1 => {
                if !matches!(block.element_type, ElementType::Lin2 | ElementType::Lin3) {
                    return Err(err(
                        path,
                        format!(
                            "unsupported 1-D element type {:?}: expected 2- or 3-node lines",
                            block.element_type
                        ),
                    ));
                }
                for e in &block.elements {
                    let edge_nodes = e
                        .nodes
                        .iter()
                        .map(|&t| node_index(t))
                        .collect::<Result<Vec<_>>>()?;
                    for g in &groups {
                        add_nodes(&mut node_sets, g, &edge_nodes);
                        mesh.edge_groups.entry(g.clone()).or_default().push(Edge {
                            nodes: edge_nodes.clone(),
                        });
                    }
                }
            }
            0 => {
                for e in &block.elements {
                    let point_nodes = e
                        .nodes
                        .iter()
                        .map(|&t| node_index(t))
                        .collect::<Result<Vec<_>>>()?;
                    for g in &groups {
                        add_nodes(&mut node_sets, g, &point_nodes);
                    }
                }
            }
            d => {
                return Err(err(
                    path,
                    format!(
                        "the mesh has {d}-D elements ({:?}); hbcontact reads 2-D meshes: mesh with gmsh -2 and keep the geometry planar",
                        block.element_type
                    ),
                ));
            }
        }
    }
    if mesh.cells.is_empty() {
        return Err(err(
            path,
            "the mesh has no 2-D cells: is the surface meshed (gmsh -2) and in a physical group?",
        ));
    }
    for c in &mesh.cells {
        for &n in &c.nodes {
            let (tag, z, scale) = node_z[n];
            if z.abs() > 1e-12 * (1.0 + scale) {
                return Err(err(
                    path,
                    format!("node {tag} has z = {z}: hbcontact is 2-D, draw the geometry in the z = 0 plane"),
                ));
            }
        }
    }
    mesh.node_groups = node_sets
        .into_iter()
        .map(|(k, v)| (k, v.into_iter().collect()))
        .collect();

    // Orientation: counter-clockwise; degenerate cells are an error.
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in &mesh.nodes {
        for c in 0..2 {
            lo[c] = lo[c].min(p[c]);
            hi[c] = hi[c].max(p[c]);
        }
    }
    let bbox_area = ((hi[0] - lo[0]) * (hi[1] - lo[1])).max(f64::MIN_POSITIVE);
    for (i, cell) in mesh.cells.iter_mut().enumerate() {
        let a2 = signed_area2(&mesh.nodes, cell);
        if a2.abs() < 2e-12 * bbox_area {
            let p = mesh.nodes[cell.nodes[0]];
            return Err(err(
                path,
                format!("cell {i} (first node at ({}, {})) is degenerate (zero area): check the geometry there", p[0], p[1]),
            ));
        }
        if a2 < 0.0 {
            reverse(cell);
        }
    }
    Ok(mesh)
}
