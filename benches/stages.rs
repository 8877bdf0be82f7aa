//! Per-stage wall times of the linear pipeline on the slender cantilever at about 1e4, 1e5 and
//! 1e6 dofs, and the ratio of the solve stage to faer's numeric factorization alone.
//!
//! `cargo bench --bench stages [-- 1e4 1e5]` (default: all three sizes). Times come from one
//! run on a shared machine: compare ratios within a row, not absolute seconds across runs.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use faer::c64;
use hbcontact::fem::DofMap;
use hbcontact::fem::{self, MassKind, Material, PlaneModel};
use hbcontact::hbm::{self, HarmonicInput, HbSettings, System};
use hbcontact::mesh::gmsh::{mesh_geometry, MeshRequest};
use hbcontact::mesh::msh::read_msh;
use hbcontact::output::{write_pvd, write_vtu, Field};

fn main() {
    let targets: Vec<f64> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let targets = if targets.is_empty() {
        vec![1e4, 1e5, 1e6]
    } else {
        targets
    };
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let work = root.join("output").join("bench-stages");
    let _ = std::fs::create_dir_all(&work);
    let material = Material {
        youngs_modulus: 210e9,
        poisson_ratio: 0.3,
        density: 7800.0,
        model: PlaneModel::PlaneStrain,
        thickness: 1.0,
    };
    println!(
        "{:>9} {:>9} {:>8} {:>8} {:>9} {:>8} {:>8} {:>8} {:>8} {:>10}",
        "target",
        "dofs",
        "mesh s",
        "read s",
        "assemble",
        "analyse",
        "factor",
        "solve",
        "write",
        "solve/fac"
    );
    // dofs ≈ C / h² for quadratic triangles on the 1 × 0.02 strip; calibrate C on a coarse mesh.
    let mut constant: Option<f64> = None;
    for target in targets {
        let h = match constant {
            Some(c) => (c / target).sqrt(),
            // Calibrate on the first size: Tri6 on the 1 × 0.02 strip has about 0.19/h² dofs.
            None => (0.19 / target).sqrt(),
        };
        let request = MeshRequest {
            geo: root.join("geometries/cantilever.geo"),
            parameters: BTreeMap::from([("L".to_string(), 1.0), ("H".to_string(), 0.02)]),
            mesh_size: Some(h),
            order: 2,
            quads: false,
            gmsh: None,
            trusted: false,
        };
        let t = Instant::now();
        let meshed = match mesh_geometry(&request, &work.join("cache")) {
            Ok(m) => m,
            Err(e) => {
                eprintln!("mesh failed: {e}");
                return;
            }
        };
        let t_mesh = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let mesh = match read_msh(&meshed.msh) {
            Ok(m) => m,
            Err(e) => {
                eprintln!("read failed: {e}");
                return;
            }
        };
        let t_read = t.elapsed().as_secs_f64();
        let ndof = 2 * mesh.nodes.len();
        constant.get_or_insert(ndof as f64 * h * h);

        let t = Instant::now();
        let (k, m) = match (
            fem::assemble_stiffness(&mesh, &material),
            fem::assemble_mass(&mesh, &material, MassKind::Consistent),
        ) {
            (Ok(k), Ok(m)) => (k, m),
            _ => {
                eprintln!("assembly failed");
                return;
            }
        };
        let mut active = vec![false; ndof];
        for n in mesh.body_nodes() {
            active[2 * n] = true;
            active[2 * n + 1] = true;
        }
        let mut held = vec![false; ndof];
        for &n in &mesh.node_groups["clamp"] {
            held[2 * n] = true;
            held[2 * n + 1] = true;
        }
        let dofs = DofMap::new(&active, &held);
        let tip = fem::edge_traction_load(&mesh, &mesh.edge_groups["tip"], [0.0, 1.0e3], 1.0);
        let force: Vec<c64> = dofs.free.iter().map(|&d| c64::new(tip[d], 0.0)).collect();
        let np = dofs.prescribed.len();
        let inputs = BTreeMap::from([(
            1,
            HarmonicInput {
                force,
                motion: vec![c64::new(0.0, 0.0); np],
            },
        )]);
        let t_assemble = t.elapsed().as_secs_f64();

        let t = Instant::now();
        let system = match System::new(
            dofs,
            &k,
            &m,
            Some((0.5, 0.0)),
            2.0 * std::f64::consts::PI * 10.0,
            inputs,
            None,
        ) {
            Ok(s) => s,
            Err(e) => {
                eprintln!("{e}");
                return;
            }
        };
        let t_analyse = t.elapsed().as_secs_f64();
        // faer's numeric factorization alone, and the whole solve stage as the pipeline runs
        // it (factor + solve + backward-error check); each the faster of two runs, so that
        // first-touch page faults do not decide the ratio.
        let mut t_factor = f64::INFINITY;
        let mut t_solve = f64::INFINITY;
        let settings = HbSettings {
            harmonics: 1,
            samples: 64,
            c_scale: 1.0,
            tolerance: 1e-8,
            max_seconds: 3600.0,
            max_iterations: 10,
        };
        let mut solution = None;
        for _ in 0..2 {
            let t = Instant::now();
            let lu = system.factor(1, None);
            t_factor = t_factor.min(t.elapsed().as_secs_f64());
            drop(lu);
            let t = Instant::now();
            match hbm::solve(&system, None, &settings, &hbcontact::Silent) {
                Ok(s) => solution = Some(s),
                Err(e) => {
                    eprintln!("{e}");
                    return;
                }
            }
            t_solve = t_solve.min(t.elapsed().as_secs_f64());
        }
        let Some(solution) = solution else { return };

        let t = Instant::now();
        let u = solution.field_at(&system.dofs, 0.0, 0);
        let disp: Vec<f64> = u.chunks(2).flat_map(|c| [c[0], c[1], 0.0]).collect();
        let dir = work.join(format!("series-{}", ndof));
        let _ = std::fs::create_dir_all(&dir);
        let field = Field {
            name: "displacement".into(),
            components: 3,
            values: disp,
        };
        if let Err(e) = write_vtu(&dir.join("frame_0000.vtu"), &mesh, &[field], &[]) {
            eprintln!("{e}");
        }
        let _ = write_pvd(&dir.join("series.pvd"), &[(0.0, "frame_0000.vtu".into())]);
        let t_write = t.elapsed().as_secs_f64();
        println!(
            "{:>9.0e} {:>9} {:>8.3} {:>8.3} {:>9.3} {:>8.3} {:>8.3} {:>8.3} {:>8.3} {:>10.2}",
            target,
            ndof,
            t_mesh,
            t_read,
            t_assemble,
            t_analyse,
            t_factor,
            t_solve,
            t_write,
            t_solve / t_factor
        );
    }
}
