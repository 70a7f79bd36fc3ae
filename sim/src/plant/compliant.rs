//! The compliant plant: the carriages as rigid bodies with six degrees of freedom on their guide
//! blocks, the links of a rapier3d-f64 multibody.
//!
//! Each carriage is joined to the body that carries it (the ground, or the carriage below it) by
//! a rapier multibody joint with all six directions free (`GenericJoint` with no locked axes), its
//! frame at the carriage's anchor (the centroid of its blocks, `vmt_model::structure`), the body
//! with its own mass, centre of mass and inertia tensor. The joint coordinates are the carriage's
//! translation `t` along the parent's axes and its rotation `θ` about its anchor; the translation
//! along the axis is the axis coordinate, the other five are the small deflections on the blocks.
//! rapier gives the multibody's joint-space mass matrix `M(q)` (the carriages' masses and
//! inertias through the chain, a table's weight acting on its saddle), the bias accelerations
//! `b` (gravity at each centre of mass, Coriolis) and the forward kinematics.
//!
//! Equations, every fine step `h` (the plant step), in joint coordinates `x` (m, rad):
//!
//! ```text
//! M ẍ = τ_blocks + τ_nut + τ_friction + τ_process + M b
//! τ_blocks   = −K x − C ẋ                  each carriage's blocks (vmt_model::structure)
//! τ_nut      = [F_s u, r_n × F_s u]         the screw force F_s at the nut r_n (from the anchor)
//! τ_friction = [−F_f u, 0]                  the guide friction at the blocks' centroid
//! τ_process  = Σ_chain [F, (p − a_j) × F]   a force F on the tool at p (−F on the workpiece)
//! ```
//!
//! with the drives of `vmt_model::drive` (motor side, screw with backlash, LuGre friction,
//! current loop), whose screw stretches to the nut's axial position `t_u + (θ × r_n)·u`.
//! Integrator: semi-implicit Euler, `ẋ += h (M⁻¹ τ + b)`, `x += h ẋ`, the drives' integrator,
//! with `M⁻¹` and `b` frozen over a macro step of about [`MULTIBODY_STEP_S`]: every macro step
//! rapier takes the coordinates and velocities of the fine integration, advances the multibody
//! once without forces, and hands back its factorised mass matrix and the bias `b = (v⁺ − v)/H`.
//! The block springs are ours, not rapier's joint springs: those are implicit (backward Euler),
//! whose numerical damping `ζ ≈ ωh/2` at the plant step (0.1 at 250 Hz and 125 µs) would exceed
//! the blocks' own.
//!
//! Stability: the block modes are the stiffest of the structure; [`CompliantPlant::new`] takes
//! the eigenvalues of `M⁻¹K` at the start and refuses a step beyond half the semi-implicit Euler
//! limit of the stiffest (as for the drive modes, where the step keeps the mode's frequency
//! within 5 %). The carriages start at their static equilibrium under gravity across their axes.

use super::{AxisLayout, Plant, PlantError};
use nalgebra::{DMatrix, Matrix6, SMatrix, SVector, SymmetricEigen, Vector3, Vector6};
use rapier3d_f64::prelude::*;
use vmt_model::Axis;
use vmt_model::drive::axis::symplectic_euler_limit;
use vmt_model::drive::{AxisCommand, CarriageState, Drive};
use vmt_model::kinematics::Deflection;
use vmt_model::structure::{Structure, axis_unit};

/// The target macro step, s (as the rigid multibody's).
pub const MULTIBODY_STEP_S: f64 = super::multibody::MULTIBODY_STEP_S;

/// Joint coordinates of the three carriages: `[t, θ]` of X, then Y, then Z.
type Dofs = SVector<f64, 18>;
type Mat = SMatrix<f64, 18, 18>;

/// One carriage in the multibody.
#[derive(Clone, Debug)]
struct Link {
    axis: usize,
    joint: MultibodyJointHandle,
    sign: f64,
    /// Axis coordinate at joint translation 0, m.
    q0: f64,
    /// Anchor with every axis at zero, m.
    anchor: Vector3<f64>,
    /// Nut from the anchor, m.
    nut: Vector3<f64>,
    stiffness: Matrix6<f64>,
    damping: Matrix6<f64>,
    /// The carriage carrying this one.
    parent: Option<usize>,
}

impl Link {
    /// The nut's axial displacement (m) and velocity (m/s) from the joint coordinates.
    fn nut(&self, x: &Dofs, v: &Dofs) -> (f64, f64) {
        let s = 6 * self.axis;
        let u = axis_unit(Axis::ALL[self.axis]);
        let th = Vector3::new(x[s + 3], x[s + 4], x[s + 5]);
        let w = Vector3::new(v[s + 3], v[s + 4], v[s + 5]);
        (
            x[s + self.axis] + th.cross(&self.nut).dot(&u),
            v[s + self.axis] + w.cross(&self.nut).dot(&u),
        )
    }
}

/// The rapier multibody of the carriages on their compliant guideways, driven by our drives.
pub struct CompliantPlant {
    world: PhysicsWorld,
    links: [Link; 3],
    drives: [Drive; 3],
    carriages: [CarriageState; 3],
    x: Dofs,
    v: Dofs,
    inv_mass: Mat,
    bias: Dofs,
    /// Generalized force of the process (a force on the tool), constant until set again.
    process: Dofs,
    /// The tool point from the spindle frame's origin, m.
    tool_offset: Vector3<f64>,
    /// The carriages and their blocks.
    structure: Structure,
    /// The carriages of each of rapier's multibodies ([`CompliantPlant::multibodies`]), fixed
    /// once the multibody is built.
    groups: Vec<Vec<usize>>,
    fine_per_macro: usize,
    fine_done: usize,
    elapsed_s: f64,
    macro_steps: u64,
}

impl CompliantPlant {
    /// A plant at rest with the carriages where their motors are, at their static deflection
    /// under gravity; `structure` gives the carriages, `layout` how they are chained, `h` the
    /// fine step (s), `tool_offset` the tool point in the spindle frame (m).
    pub fn new(
        drives: [Drive; 3],
        layout: &[AxisLayout; 3],
        structure: &Structure,
        tool_offset: Vector3<f64>,
        h: f64,
    ) -> Result<Self, PlantError> {
        for c in &structure.carriages {
            c.validate().map_err(PlantError::Structure)?;
        }
        let mut world = PhysicsWorld::new();
        world.gravity = Vector::new(0.0, 0.0, -super::GRAVITY_M_S2);
        world.integration_parameters.num_solver_iterations = 1;
        let p = &mut world.integration_parameters;
        p.num_internal_stabilization_iterations = 0;
        p.max_ccd_substeps = 0;
        let ground = world.bodies.insert(RigidBodyBuilder::fixed().build());
        let q0: [f64; 3] = std::array::from_fn(|i| drives[i].motor_position_m);
        // Each carriage's anchor in the world at the start: its place with the axes at zero
        // moved by its own and its carriers' travel.
        let world_anchor = |i: usize| -> Vector3<f64> {
            let mut a = structure.carriages[i].anchor_m();
            let mut k = Some(i);
            while let Some(j) = k {
                a += axis_unit(Axis::ALL[j]) * (layout[j].sign * q0[j]);
                k = layout[j].parent.map(|p| p.index());
            }
            a
        };
        let mut order: Vec<usize> = (0..3).collect();
        order.sort_by_key(|&i| depth(layout, i));
        let mut bodies: [Option<RigidBodyHandle>; 3] = [None; 3];
        let mut joints: [Option<MultibodyJointHandle>; 3] = [None; 3];
        for &i in &order {
            let c = &structure.carriages[i];
            let anchor = world_anchor(i);
            let com = c.com_m - c.anchor_m();
            let mass = MassProperties::with_inertia_matrix(
                Vector::new(com.x, com.y, com.z),
                c.mass_kg,
                glam_matrix(&c.inertia_kg_m2),
            );
            let body = world.bodies.insert(
                RigidBodyBuilder::dynamic()
                    .translation(Vector::new(anchor.x, anchor.y, anchor.z))
                    .additional_mass_properties(mass)
                    // A carriage standing still is not asleep: rapier would stop giving its
                    // gravity (a held head floated up by its screw's sag after 0.5 s).
                    .can_sleep(false)
                    .build(),
            );
            let (parent, parent_anchor) = match layout[i].parent {
                Some(p) => (
                    bodies[p.index()].ok_or(PlantError::Joint(layout[i].axis))?,
                    world_anchor(p.index()),
                ),
                None => (ground, Vector3::zeros()),
            };
            let rel = anchor - parent_anchor;
            let joint = GenericJointBuilder::new(JointAxesMask::empty())
                .local_anchor1(Vector::new(rel.x, rel.y, rel.z))
                .contacts_enabled(false)
                .build();
            let handle = world
                .multibody_joints
                .insert(parent, body, joint, true)
                .ok_or(PlantError::Joint(layout[i].axis))?;
            bodies[i] = Some(body);
            joints[i] = Some(handle);
        }
        // No implicit joint damping of rapier's own (its default on angular coordinates): the
        // blocks' damping is ours.
        for j in joints.iter().flatten() {
            if let Some((mb, _)) = world.multibody_joints.get_mut(*j) {
                mb.damping_mut().fill(0.0);
            }
        }
        let links: [Link; 3] = std::array::from_fn(|i| {
            let c = &structure.carriages[i];
            Link {
                axis: i,
                joint: joints[i].expect("every carriage was inserted"),
                sign: layout[i].sign,
                q0: q0[i],
                anchor: c.anchor_m(),
                nut: c.nut_m - c.anchor_m(),
                stiffness: c.stiffness(),
                damping: c.damping(),
                parent: layout[i].parent.map(|p| p.index()),
            }
        });
        let fine_per_macro = ((MULTIBODY_STEP_S / h).round() as usize).max(1);
        let mut plant = Self {
            world,
            links,
            drives,
            carriages: std::array::from_fn(|i| CarriageState {
                position_m: q0[i],
                ..Default::default()
            }),
            x: Dofs::zeros(),
            v: Dofs::zeros(),
            inv_mass: Mat::zeros(),
            bias: Dofs::zeros(),
            process: Dofs::zeros(),
            tool_offset,
            structure: structure.clone(),
            groups: Vec::new(),
            fine_per_macro,
            fine_done: 0,
            elapsed_s: 0.0,
            macro_steps: 0,
        };
        plant.groups = plant.multibodies();
        plant.refresh(h);
        plant.check_step(h)?;
        plant.settle_under_gravity()?;
        plant.sync();
        Ok(plant)
    }

    /// The joint-space mass matrix at the start and the blocks' stiffness and damping matrices
    /// on all 18 coordinates.
    fn matrices(&self) -> Option<(DMatrix<f64>, DMatrix<f64>, DMatrix<f64>)> {
        let inv = DMatrix::from_fn(18, 18, |r, c| self.inv_mass[(r, c)]);
        let m = inv.try_inverse()?;
        let (mut k, mut c) = (DMatrix::zeros(18, 18), DMatrix::zeros(18, 18));
        for (i, l) in self.links.iter().enumerate() {
            k.view_mut((6 * i, 6 * i), (6, 6)).copy_from(&l.stiffness);
            c.view_mut((6 * i, 6 * i), (6, 6)).copy_from(&l.damping);
        }
        Some((m, k, c))
    }

    /// The natural frequencies (Hz) of the carriages on their blocks at the start (the axes
    /// held by nothing: their coordinates are the rigid-body modes at 0 Hz), with each mode's
    /// damping ratio and the axis whose carriage moves most in it, lowest first.
    pub fn modes(&self) -> Vec<(f64, f64, Axis)> {
        let Some((m, k, c)) = self.matrices() else {
            return Vec::new();
        };
        let Some(l) = m.clone().cholesky() else {
            return Vec::new();
        };
        let l = l.l();
        let Some(li) = l.clone().try_inverse() else {
            return Vec::new();
        };
        let a = &li * &k * li.transpose();
        let sym = (&a + a.transpose()) * 0.5;
        let Some(eig) = SymmetricEigen::try_new(sym, f64::EPSILON, 10_000) else {
            return Vec::new();
        };
        let mut out: Vec<(f64, f64, Axis)> = (0..18)
            .filter(|&j| eig.eigenvalues[j] > 1e-6 * eig.eigenvalues.amax())
            .map(|j| {
                let w2 = eig.eigenvalues[j];
                let phi = li.transpose() * eig.eigenvectors.column(j);
                let cm = (phi.transpose() * &c * &phi)[(0, 0)];
                let w = w2.sqrt();
                let most = (0..3)
                    .max_by(|&p, &q| {
                        let e = |i: usize| phi.rows(6 * i, 6).norm_squared();
                        e(p).total_cmp(&e(q))
                    })
                    .unwrap_or(0);
                (w / std::f64::consts::TAU, cm / (2.0 * w), Axis::ALL[most])
            })
            .collect();
        out.sort_by(|a, b| a.0.total_cmp(&b.0));
        out
    }

    /// Refuses a step `h` beyond half the semi-implicit Euler limit of the stiffest block mode.
    fn check_step(&self, h: f64) -> Result<(), PlantError> {
        let modes = self.modes();
        let Some(&(hz, zeta, axis)) = modes.last() else {
            return Ok(());
        };
        let w = hz * std::f64::consts::TAU;
        let limit = symplectic_euler_limit(w * w, 2.0 * zeta * w, 1.0);
        let accepted = limit * crate::simulate::STABLE_STEP_FRACTION;
        if h > accepted {
            return Err(PlantError::StepTooCoarse {
                axis,
                mode_hz: hz,
                step_us: h * 1e6,
                accepted_us: accepted * 1e6,
            });
        }
        Ok(())
    }

    /// Puts each carriage at its static deflection under gravity in the five directions its
    /// blocks hold (the axes held where they are: their drives take the rest).
    fn settle_under_gravity(&mut self) -> Result<(), PlantError> {
        let Some((m, k, _)) = self.matrices() else {
            return Ok(());
        };
        let b = nalgebra::DVector::from_fn(18, |r, _| self.bias[r]);
        let g = &m * b;
        let free: Vec<usize> = (0..18).filter(|&r| r % 6 != r / 6).collect();
        let kr = DMatrix::from_fn(free.len(), free.len(), |r, c| k[(free[r], free[c])]);
        let gr = nalgebra::DVector::from_fn(free.len(), |r, _| g[free[r]]);
        let Some(x) = kr.lu().solve(&gr) else {
            return Err(PlantError::Joint(Axis::X));
        };
        for (r, &j) in free.iter().enumerate() {
            self.x[j] = x[r];
        }
        Ok(())
    }

    /// How many macro steps rapier has taken since the plant was built.
    pub fn macro_steps(&self) -> u64 {
        self.macro_steps
    }

    /// Each carriage's small motion on its blocks: translation across its axis (m, the axis'
    /// own component zero) and rotation about its anchor (rad), machine axes.
    pub fn motions(&self) -> [(Vector3<f64>, Vector3<f64>); 3] {
        std::array::from_fn(|i| {
            let s = 6 * i;
            let mut t = Vector3::new(self.x[s], self.x[s + 1], self.x[s + 2]);
            t[i] = 0.0;
            (t, Vector3::new(self.x[s + 3], self.x[s + 4], self.x[s + 5]))
        })
    }

    /// The force of each block on its carriage (N, machine axes) now, X's blocks first.
    pub fn block_forces(&self) -> [Vec<Vector3<f64>>; 3] {
        std::array::from_fn(|i| {
            let c = &self.structure.carriages[i];
            let a = c.anchor_m();
            let s = 6 * i;
            let t = Vector3::new(self.x[s], self.x[s + 1], self.x[s + 2]);
            let th = Vector3::new(self.x[s + 3], self.x[s + 4], self.x[s + 5]);
            let tv = Vector3::new(self.v[s], self.v[s + 1], self.v[s + 2]);
            let w = Vector3::new(self.v[s + 3], self.v[s + 4], self.v[s + 5]);
            c.blocks
                .iter()
                .map(|b| {
                    let r = b.position_m - a;
                    let (n, l) = (b.normal, b.lateral(c.axis));
                    let (d, dv) = (t + th.cross(&r), tv + w.cross(&r));
                    -(n * (b.normal_stiffness_n_per_m * n.dot(&d)
                        + b.normal_damping_n_s_per_m * n.dot(&dv))
                        + l * (b.lateral_stiffness_n_per_m * l.dot(&d)
                            + b.lateral_damping_n_s_per_m * l.dot(&dv)))
                })
                .collect()
        })
    }

    /// The world position of carriage `i`'s anchor now, m.
    fn world_anchor(&self, i: usize) -> Vector3<f64> {
        let mut a = self.links[i].anchor;
        let mut k = Some(i);
        while let Some(j) = k {
            a += axis_unit(Axis::ALL[j]) * (self.links[j].sign * self.carriages[j].position_m);
            k = self.links[j].parent;
        }
        a
    }

    /// rapier's joint-space dynamics at the present configuration: its inverse mass matrix and
    /// the bias of an unforced step of `big_h` seconds.
    fn refresh(&mut self, big_h: f64) {
        self.sync();
        self.world.integration_parameters.dt = big_h;
        self.world.step();
        self.macro_steps += 1;
        // No sync after the step: nothing reads rapier's state between macro steps, and the
        // next refresh writes the fine integration's state in before it steps again.
        let mut inv = Mat::zeros();
        let mut after = Dofs::zeros();
        for group in &self.groups {
            let Some((mb, _)) = self.world.multibody_joints.get(self.links[group[0]].joint) else {
                continue;
            };
            // The columns of M⁻¹ of this multibody's coordinates, solved at once.
            let n = mb.ndofs();
            let mut cols = DMatrix::<f64>::identity(n, n);
            if !mb.inv_augmented_mass().solve_mut(&mut cols) {
                continue;
            }
            // Each carriage of it with its coordinates' place in the multibody.
            let members: Vec<(usize, usize)> = group
                .iter()
                .filter_map(|&i| {
                    let (_, id) = self.world.multibody_joints.get(self.links[i].joint)?;
                    Some((i, mb.link(id)?.assembly_id()))
                })
                .collect();
            for &(i, ai) in &members {
                let vel = mb.generalized_velocity();
                for k in 0..6 {
                    after[6 * i + k] = vel[ai + k];
                }
                for &(j, aj) in &members {
                    for r in 0..6 {
                        for k in 0..6 {
                            inv[(6 * i + r, 6 * j + k)] = cols[(ai + r, aj + k)];
                        }
                    }
                }
            }
        }
        self.inv_mass = inv;
        self.bias = (after - self.v) / big_h;
    }

    /// The carriages (indices of `links`) of each of rapier's multibodies: the carriages that
    /// ride on one another share one.
    fn multibodies(&self) -> Vec<Vec<usize>> {
        let mut out: Vec<Vec<usize>> = Vec::new();
        for (i, l) in self.links.iter().enumerate() {
            let Some((mb, _)) = self.world.multibody_joints.get(l.joint) else {
                continue;
            };
            let same = |g: &Vec<usize>| {
                self.world
                    .multibody_joints
                    .get(self.links[g[0]].joint)
                    .is_some_and(|(m, _)| std::ptr::eq(m, mb))
            };
            match out.iter_mut().find(|g| same(g)) {
                Some(g) => g.push(i),
                None => out.push(vec![i]),
            }
        }
        out
    }

    /// Writes the fine integration's coordinates and velocities into the multibody and places
    /// its bodies (once per multibody).
    fn sync(&mut self) {
        for group in &self.groups {
            for &i in group {
                let l = &self.links[i];
                let Some((mb, id)) = self.world.multibody_joints.get_mut(l.joint) else {
                    continue;
                };
                let Some(link) = mb.link(id) else { continue };
                let a = link.assembly_id();
                let coords = link.joint().coords();
                let mut disp = vec![0.0; mb.ndofs()];
                for k in 0..6 {
                    disp[a + k] = self.x[6 * i + k] - coords[k];
                }
                mb.apply_displacements(&disp);
                let mut vel = mb.generalized_velocity_mut();
                for k in 0..6 {
                    vel[a + k] = self.v[6 * i + k];
                }
            }
            if let Some((mb, _)) = self
                .world
                .multibody_joints
                .get_mut(self.links[group[0]].joint)
            {
                mb.forward_kinematics(&self.world.bodies, false);
                mb.update_rigid_bodies(&mut self.world.bodies, false);
            }
        }
    }
}

/// Number of carriages between axis `i` and the ground.
fn depth(layout: &[AxisLayout; 3], i: usize) -> usize {
    let mut d = 0;
    let mut p = layout[i].parent;
    while let Some(a) = p {
        d += 1;
        p = layout[a.index()].parent;
    }
    d
}

/// A nalgebra 3x3 matrix as rapier's (glam) matrix.
fn glam_matrix(m: &nalgebra::Matrix3<f64>) -> rapier3d_f64::math::Matrix {
    rapier3d_f64::math::Matrix::from_cols(
        Vector::new(m[(0, 0)], m[(1, 0)], m[(2, 0)]),
        Vector::new(m[(0, 1)], m[(1, 1)], m[(2, 1)]),
        Vector::new(m[(0, 2)], m[(1, 2)], m[(2, 2)]),
    )
}

impl Plant for CompliantPlant {
    fn control(&mut self, commands: &[AxisCommand; 3], period_s: f64) {
        for ((d, c), k) in self.drives.iter_mut().zip(commands).zip(&self.carriages) {
            d.control(c, k.position_m, period_s);
        }
    }

    fn step(&mut self, h: f64) {
        let mut nut = [(0.0, 0.0); 3];
        for (n, l) in nut.iter_mut().zip(&self.links) {
            let (x, v) = l.nut(&self.x, &self.v);
            *n = (l.q0 + l.sign * x, l.sign * v);
        }
        let [d0, d1, d2] = self.drives.each_mut();
        let [c0, c1, c2] = self.carriages.each_mut();
        Drive::step_all_at_nut([(d0, c0), (d1, c1), (d2, c2)], nut, [0.0; 3], h);
        let mut tau = self.process;
        for (i, l) in self.links.iter().enumerate() {
            let s = 6 * i;
            let x = self.x.fixed_rows::<6>(s);
            let v = self.v.fixed_rows::<6>(s);
            let mut f: Vector6<f64> = -(l.stiffness * x + l.damping * v);
            let screw = l.sign * self.drives[i].screw_force_n;
            f[i] += screw - l.sign * self.carriages[i].friction_force_n;
            let u = axis_unit(Axis::ALL[i]);
            let moment = l.nut.cross(&(u * screw));
            f[3] += moment.x;
            f[4] += moment.y;
            f[5] += moment.z;
            let mut t = tau.fixed_rows_mut::<6>(s);
            t += f;
        }
        self.v += (self.inv_mass * tau + self.bias) * h;
        self.x += self.v * h;
        for (i, (c, l)) in self.carriages.iter_mut().zip(&self.links).enumerate() {
            c.position_m = l.q0 + l.sign * self.x[6 * i + i];
            c.velocity_m_s = l.sign * self.v[6 * i + i];
        }
        self.elapsed_s += h;
        self.fine_done += 1;
        if self.fine_done >= self.fine_per_macro {
            let big_h = self.elapsed_s;
            self.refresh(big_h);
            self.fine_done = 0;
            self.elapsed_s = 0.0;
        }
    }

    fn drive(&self, i: usize) -> &Drive {
        &self.drives[i]
    }

    fn carriages(&self) -> [CarriageState; 3] {
        self.carriages
    }

    fn carriage_motions(&self) -> Option<[(Vector3<f64>, Vector3<f64>); 3]> {
        Some(self.motions())
    }

    fn block_normal_forces(&self) -> Vec<f64> {
        let forces = self.block_forces();
        self.structure
            .carriages
            .iter()
            .zip(&forces)
            .flat_map(|(c, f)| c.blocks.iter().zip(f).map(|(b, f)| b.normal.dot(f)))
            .collect()
    }

    fn deflections(&self) -> Option<[Deflection; 3]> {
        let motions = self.motions();
        Some(std::array::from_fn(|i| {
            let (t, th) = motions[i];
            let l = &self.links[i];
            if l.sign > 0.0 {
                Deflection {
                    translation: t + l.anchor.cross(&th),
                    rotation: th,
                }
            } else {
                let q = axis_unit(Axis::ALL[i]) * self.carriages[i].position_m;
                Deflection {
                    translation: -t + th.cross(&(l.anchor - q)),
                    rotation: -th,
                }
            }
        }))
    }

    fn set_tool_force(&mut self, force_n: Vector3<f64>) {
        // The tool point in the world: the tool offset moved by the tool side's travel.
        let mut p = self.tool_offset;
        for (i, l) in self.links.iter().enumerate() {
            if l.sign > 0.0 {
                p += axis_unit(Axis::ALL[i]) * self.carriages[i].position_m;
            }
        }
        let mut tau = Dofs::zeros();
        for (i, l) in self.links.iter().enumerate() {
            // The tool side carries the force on the tool, the workpiece side its reaction.
            let f = force_n * l.sign;
            let m = (p - self.world_anchor(i)).cross(&f);
            for k in 0..3 {
                tau[6 * i + k] = f[k];
                tau[6 * i + 3 + k] = m[k];
            }
        }
        self.process = tau;
    }
}
