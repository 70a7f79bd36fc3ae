//! `[machine.axes.<axis>.carriage]`: each carriage as a rigid body on its guide blocks (the
//! compliant plant's structure, `vmt_model::structure`).
//!
//! ```toml
//! [machine.axes.x.carriage]        # positions in the machine frame with every axis at zero, mm
//! size_mm = [800.0, 450.0, 100.0]  # its box: edges along X, Y, Z
//! center_mm = [250.0, 200.0, -200.0]
//! # com_mm = [...]                 # centre of mass; default: the box's centre
//! # inertia_kg_m2 = [[...], [...], [...]]  # about the centre of mass; default: the box's
//! nut_mm = [250.0, 200.0, -290.0]  # where the ball nut pushes it
//! block_normal = "z"               # the blocks' load direction: x, y or z (across the axis)
//! blocks_mm = [[100.0, 50.0, -250.0], ...]
//! block_normal_n_per_um = 400.0    # per block, along the normal and across the rail
//! block_lateral_n_per_um = 300.0
//! block_normal_damping_n_s_per_m = 3.0e4
//! block_lateral_damping_n_s_per_m = 3.0e4
//! ```
//!
//! The carriage's own mass is its axis' moving mass less what it carries (the topology's
//! chain); the box gives the inertia of that mass when no tensor is given.

use crate::build::{in_range, positive};
use crate::error::{Invalid, KeyPath};
use crate::schema::Numbers;
use nalgebra::{Matrix3, Vector3};
use serde::Deserialize;
use vmt_model::Axis;
use vmt_model::kinematics::Topology;
use vmt_model::structure::{Carriage, GuideBlock, Structure, StructureError, box_inertia};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CarriageToml {
    pub size_mm: Numbers<3>,
    pub center_mm: Numbers<3>,
    pub com_mm: Option<Numbers<3>>,
    pub inertia_kg_m2: Option<[Numbers<3>; 3]>,
    pub nut_mm: Numbers<3>,
    pub block_normal: String,
    pub blocks_mm: Vec<Numbers<3>>,
    pub block_normal_n_per_um: f64,
    pub block_lateral_n_per_um: f64,
    pub block_normal_damping_n_s_per_m: f64,
    pub block_lateral_damping_n_s_per_m: f64,
}

type R<T> = Result<T, Invalid>;

/// Largest block stiffness accepted, N/µm (catalogue blocks: 100–2000).
const MAX_BLOCK_N_PER_UM: f64 = 1e6;

/// The machine's structure from the axes' carriage sections: all three or none.
pub fn structure(
    raw: [Option<&CarriageToml>; 3],
    topology: &Topology,
    moving_kg: [f64; 3],
) -> R<Option<Structure>> {
    let root = KeyPath::of(&["machine", "axes"]);
    if raw.iter().all(Option::is_none) {
        return Ok(None);
    }
    let layout = vmt_sim::plant::layout(topology, moving_kg)
        .map_err(|e| Invalid::new(root.clone(), e.to_string()))?;
    let mut out = Vec::new();
    for (i, c) in raw.into_iter().enumerate() {
        let axis = Axis::ALL[i];
        let p = root.key(&axis.to_string().to_lowercase());
        let Some(c) = c else {
            return Err(Invalid::new(
                p.key("carriage"),
                "missing: the structure needs every axis' carriage (or none)",
            ));
        };
        out.push(carriage(c, axis, layout[i].link_mass_kg, &p)?);
    }
    let carriages: [Carriage; 3] = out
        .try_into()
        .map_err(|_| Invalid::new(root, "three carriages are needed"))?;
    Ok(Some(Structure { carriages }))
}

fn mm3(v: &Numbers<3>, p: &KeyPath) -> R<Vector3<f64>> {
    let mut out = Vector3::zeros();
    for k in 0..3 {
        out[k] = in_range(
            v.0[k],
            -10_000.0,
            10_000.0,
            &p.index(k),
            "a coordinate in mm",
        )? * 1e-3;
    }
    Ok(out)
}

fn carriage(c: &CarriageToml, axis: Axis, mass_kg: f64, axis_path: &KeyPath) -> R<Carriage> {
    let p = axis_path.key("carriage");
    let mut size = Vector3::zeros();
    for k in 0..3 {
        size[k] = positive(
            c.size_mm.0[k],
            10_000.0,
            &p.key("size_mm").index(k),
            "an edge in mm",
        )? * 1e-3;
    }
    let center = mm3(&c.center_mm, &p.key("center_mm"))?;
    let com = match &c.com_mm {
        Some(v) => mm3(v, &p.key("com_mm"))?,
        None => center,
    };
    let inertia = match &c.inertia_kg_m2 {
        Some(rows) => {
            let mut m = Matrix3::zeros();
            for (r, row) in rows.iter().enumerate() {
                for k in 0..3 {
                    let key = p.key("inertia_kg_m2").index(r).index(k);
                    m[(r, k)] = in_range(row.0[k], -1e6, 1e6, &key, "an inertia in kg·m²")?;
                }
            }
            m
        }
        None => box_inertia(mass_kg, &size),
    };
    let normal = match c.block_normal.as_str() {
        "x" => Vector3::x(),
        "y" => Vector3::y(),
        "z" => Vector3::z(),
        other => {
            return Err(Invalid::new(
                p.key("block_normal"),
                format!("`{other}` is not accepted; \"x\", \"y\" or \"z\", across the axis"),
            ));
        }
    };
    let stiffness = |v: f64, key: &str| -> R<f64> {
        Ok(positive(
            v,
            MAX_BLOCK_N_PER_UM,
            &p.key(key),
            "a block stiffness (N/µm)",
        )? * 1e6)
    };
    let damping = |v: f64, key: &str| -> R<f64> {
        in_range(v, 0.0, 1e9, &p.key(key), "a block damping (N·s/m)")
    };
    let kn = stiffness(c.block_normal_n_per_um, "block_normal_n_per_um")?;
    let kl = stiffness(c.block_lateral_n_per_um, "block_lateral_n_per_um")?;
    let cn = damping(
        c.block_normal_damping_n_s_per_m,
        "block_normal_damping_n_s_per_m",
    )?;
    let cl = damping(
        c.block_lateral_damping_n_s_per_m,
        "block_lateral_damping_n_s_per_m",
    )?;
    let mut blocks = Vec::new();
    for (k, b) in c.blocks_mm.iter().enumerate() {
        blocks.push(GuideBlock {
            position_m: mm3(b, &p.key("blocks_mm").index(k))?,
            normal,
            normal_stiffness_n_per_m: kn,
            lateral_stiffness_n_per_m: kl,
            normal_damping_n_s_per_m: cn,
            lateral_damping_n_s_per_m: cl,
        });
    }
    let carriage = Carriage {
        axis,
        mass_kg,
        com_m: com,
        inertia_kg_m2: inertia,
        box_center_m: center,
        box_size_m: size,
        nut_m: mm3(&c.nut_mm, &p.key("nut_mm"))?,
        blocks,
    };
    carriage.validate().map_err(|e| {
        let key = match &e {
            StructureError::BlockOutside { block, .. } => p.key("blocks_mm").index(*block),
            StructureError::NotPositive { .. } => p.key("block_normal_n_per_um"),
            StructureError::Inertia { .. } => p.key("inertia_kg_m2"),
            StructureError::Unheld { .. } => p.key("blocks_mm"),
            StructureError::Normal { .. } => p.key("block_normal"),
            StructureError::Mass { .. } => axis_path.key("moving_mass_kg"),
        };
        Invalid::new(key, e.to_string())
    })?;
    Ok(carriage)
}
