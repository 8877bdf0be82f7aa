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

/// The `$MeshFormat` line must be `4.1 0|1 8` (version, ASCII or binary, 8-byte sizes):
/// mshio panics on a size it has no parser for, or on digits beyond its integer type.
fn check_format_line(bytes: &[u8]) -> std::result::Result<(), String> {
    let line = bytes
        .split(|&b| b == b'\n')
        .nth(1)
        .map(String::from_utf8_lossy)
        .unwrap_or_default();
    let fields: Vec<&str> = line.split_whitespace().collect();
    let shown = crate::error::excerpt(line.trim());
    match fields.as_slice() {
        ["4.1", "0" | "1", "8"] => Ok(()),
        ["4.1", "0" | "1", size] => Err(format!(
            "$MeshFormat says sizes of {} bytes; hbcontact reads the 8-byte sizes gmsh writes (write it again with gmsh `-format msh41`)",
            crate::error::excerpt(size)
        )),
        _ => Err(format!(
            "$MeshFormat line `{shown}` is not `4.1 0 8` (ASCII) or `4.1 1 8` (binary): write it with gmsh `-format msh41`"
        )),
    }
}

pub fn read_msh(path: &Path) -> Result<Mesh2d> {
    let bytes =
        std::fs::read(path).map_err(|e| err(path, format!("cannot read the mesh file: {e}")))?;
    if !bytes.starts_with(b"$MeshFormat") {
        return Err(err(path, "not a gmsh .msh file (no $MeshFormat header)"));
    }
    check_format_line(&bytes).map_err(|why| err(path, why))?;
    // mshio has `unimplemented!` paths the format check above does not all rule out: a panic
    // in it is a file it cannot read, not a crash.
    let parsed = std::panic::catch_unwind(|| mshio::parse_msh_bytes(&bytes)).map_err(|_| {
        err(
            path,
            "the MSH reader (mshio) cannot read this file: write it again with gmsh `-format msh41`",
        )
    })?;
    let msh = parsed.map_err(|e| {
        let text = format!("{e}");
        let short: String = text.chars().take(600).collect();
        err(
            path,
            format!("cannot parse as MSH 4.1 (write it with gmsh `-format msh41`): {short}"),
        )
    })?;
    let Some(node_data) = &msh.data.nodes else {
        return Err(err(path, "the file has no $Nodes section"));
    };
    let Some(elements) = &msh.data.elements else {
        return Err(err(path, "the file has no $Elements section"));
    };
    let nodes = NodeTable::read(node_data);
    let mut reader = Reader {
        path,
        names: physical_names(&bytes),
        entity_physicals: entity_physicals(&msh),
        mesh: Mesh2d {
            nodes: nodes.positions.clone(),
            ..Default::default()
        },
        nodes,
        node_sets: BTreeMap::new(),
        seen_cells: HashMap::new(),
    };
    let any_physical_2d = elements
        .element_blocks
        .iter()
        .any(|b| b.entity_dim == 2 && !reader.physicals(2, b.entity_tag).is_empty());
    for block in &elements.element_blocks {
        reader.add_block(block, any_physical_2d)?;
    }
    reader.finish()
}

/// Entity (dim, tag) → its physical tags.
fn entity_physicals(msh: &mshio::MshFile<u64, i32, f64>) -> HashMap<(i32, i32), Vec<i32>> {
    let mut map = HashMap::new();
    if let Some(entities) = &msh.data.entities {
        for p in &entities.points {
            map.insert((0, p.tag), p.physical_tags.clone());
        }
        for c in &entities.curves {
            map.insert((1, c.tag), c.physical_tags.clone());
        }
        for s in &entities.surfaces {
            map.insert((2, s.tag), s.physical_tags.clone());
        }
        for v in &entities.volumes {
            map.insert((3, v.tag), v.physical_tags.clone());
        }
    }
    map
}

/// The nodes in file order with a tag → index map (tags need not be consecutive).
struct NodeTable {
    positions: Vec<[f64; 2]>,
    /// Per node: (tag, z, max(|x|, |y|)) for the planarity check.
    z: Vec<(u64, f64, f64)>,
    index_of: HashMap<u64, usize>,
}

impl NodeTable {
    fn read(data: &mshio::Nodes<u64, i32, f64>) -> Self {
        let mut table = NodeTable {
            positions: Vec::new(),
            z: Vec::new(),
            index_of: HashMap::new(),
        };
        let mut next_tag = data.min_node_tag;
        for block in &data.node_blocks {
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
                table.index_of.insert(tag, table.positions.len());
                table.z.push((tag, n.z, n.x.abs().max(n.y.abs())));
                table.positions.push([n.x, n.y]);
            }
        }
        table
    }
}

/// The mesh being assembled from the element blocks.
struct Reader<'a> {
    path: &'a Path,
    names: BTreeMap<(i32, i32), String>,
    entity_physicals: HashMap<(i32, i32), Vec<i32>>,
    nodes: NodeTable,
    mesh: Mesh2d,
    node_sets: BTreeMap<String, BTreeSet<usize>>,
    /// Element tag → cell index (a cell in several physical groups is listed once per group).
    seen_cells: HashMap<u64, usize>,
}

impl Reader<'_> {
    fn physicals(&self, dim: i32, tag: i32) -> &[i32] {
        self.entity_physicals
            .get(&(dim, tag))
            .map_or(&[], Vec::as_slice)
    }

    fn node_indices(&self, tags: &[u64]) -> Result<Vec<usize>> {
        tags.iter()
            .map(|tag| {
                self.nodes.index_of.get(tag).copied().ok_or_else(|| {
                    err(
                        self.path,
                        format!("an element refers to node {tag}, which is not in $Nodes"),
                    )
                })
            })
            .collect()
    }

    fn add_block(
        &mut self,
        block: &mshio::ElementBlock<u64, i32>,
        any_physical_2d: bool,
    ) -> Result<()> {
        let physicals = self.physicals(block.entity_dim, block.entity_tag).to_vec();
        let groups: Vec<String> = physicals
            .iter()
            .map(|&t| {
                self.names
                    .get(&(block.entity_dim, t))
                    .cloned()
                    .unwrap_or_else(|| format!("{}D-{t}", block.entity_dim))
            })
            .collect();
        match block.entity_dim {
            // gmsh would not save unnamed surfaces either when some are named.
            2 => self.add_cells(block, &groups, physicals.is_empty() && any_physical_2d),
            1 => self.add_edges(block, &groups),
            0 => {
                for e in &block.elements {
                    let point_nodes = self.node_indices(&e.nodes)?;
                    for g in &groups {
                        add_nodes(&mut self.node_sets, g, &point_nodes);
                    }
                }
                Ok(())
            }
            d => Err(err(
                self.path,
                format!(
                    "the mesh has {d}-D elements ({:?}); hbcontact reads 2-D meshes: mesh with gmsh -2 and keep the geometry planar",
                    block.element_type
                ),
            )),
        }
    }

    fn add_cells(
        &mut self,
        block: &mshio::ElementBlock<u64, i32>,
        groups: &[String],
        skip: bool,
    ) -> Result<()> {
        let Some(kind) = cell_kind(block.element_type) else {
            return Err(err(
                self.path,
                format!(
                    "unsupported 2-D element type {:?} (gmsh type {}); supported: 3- and 6-node triangles, 4-, 8- and 9-node quadrilaterals (mesh with -order 1 or 2)",
                    block.element_type, block.element_type as u8
                ),
            ));
        };
        if skip {
            return Ok(());
        }
        for e in &block.elements {
            let index = match self.seen_cells.get(&e.element_tag) {
                Some(&i) => i,
                None => {
                    let cell_nodes = self.node_indices(&e.nodes)?;
                    if cell_nodes.len() != kind.nodes_per_cell() {
                        return Err(err(
                            self.path,
                            format!(
                                "element {} has {} nodes, expected {}",
                                e.element_tag,
                                cell_nodes.len(),
                                kind.nodes_per_cell()
                            ),
                        ));
                    }
                    self.mesh.cells.push(Cell {
                        kind,
                        nodes: cell_nodes,
                    });
                    self.seen_cells
                        .insert(e.element_tag, self.mesh.cells.len() - 1);
                    self.mesh.cells.len() - 1
                }
            };
            for g in groups {
                self.mesh
                    .cell_groups
                    .entry(g.clone())
                    .or_default()
                    .push(index);
                self.node_sets
                    .entry(g.clone())
                    .or_default()
                    .extend(self.mesh.cells[index].nodes.iter().copied());
            }
        }
        Ok(())
    }

    fn add_edges(
        &mut self,
        block: &mshio::ElementBlock<u64, i32>,
        groups: &[String],
    ) -> Result<()> {
        if !matches!(block.element_type, ElementType::Lin2 | ElementType::Lin3) {
            return Err(err(
                self.path,
                format!(
                    "unsupported 1-D element type {:?}: expected 2- or 3-node lines",
                    block.element_type
                ),
            ));
        }
        for e in &block.elements {
            let edge_nodes = self.node_indices(&e.nodes)?;
            for g in groups {
                add_nodes(&mut self.node_sets, g, &edge_nodes);
                self.mesh
                    .edge_groups
                    .entry(g.clone())
                    .or_default()
                    .push(Edge {
                        nodes: edge_nodes.clone(),
                    });
            }
        }
        Ok(())
    }

    /// Checks (cells exist, planar, none degenerate), counter-clockwise orientation, and the
    /// node groups.
    fn finish(mut self) -> Result<Mesh2d> {
        let path = self.path;
        if self.mesh.cells.is_empty() {
            return Err(err(
                path,
                "the mesh has no 2-D cells: is the surface meshed (gmsh -2) and in a physical group?",
            ));
        }
        let bad = (self.mesh.nodes.iter().zip(&self.nodes.z))
            .find(|([x, y], &(_, z, _))| !(x.is_finite() && y.is_finite() && z.is_finite()));
        if let Some(([x, y], &(tag, z, _))) = bad {
            return Err(err(
                path,
                format!("node {tag} is at ({x}, {y}, {z}): every coordinate must be a finite number (the file is damaged; mesh it again)"),
            ));
        }
        for &n in self.mesh.cells.iter().flat_map(|c| &c.nodes) {
            let (tag, z, scale) = self.nodes.z[n];
            if z.abs() > 1e-12 * (1.0 + scale) {
                return Err(err(
                    path,
                    format!("node {tag} has z = {z}: hbcontact is 2-D, draw the geometry in the z = 0 plane"),
                ));
            }
        }
        self.mesh.node_groups = std::mem::take(&mut self.node_sets)
            .into_iter()
            .map(|(k, v)| (k, v.into_iter().collect()))
            .collect();
        // A named group with no elements (an empty list in the .geo) stays, empty, so that
        // it is reported rather than silently missing.
        for name in self.names.values() {
            self.mesh.node_groups.entry(name.clone()).or_default();
        }
        orient_cells(path, &mut self.mesh)?;
        Ok(self.mesh)
    }
}

/// Make every cell counter-clockwise; degenerate (zero-area) cells are an error.
fn orient_cells(path: &Path, mesh: &mut Mesh2d) -> Result<()> {
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
    Ok(())
}
