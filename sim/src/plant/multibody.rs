//! The multibody plant: the carriages as links of a rapier3d-f64 multibody.
//!
//! The ground is a fixed body; each side of the topology is a chain of prismatic multibody
//! joints from the ground outwards (contacts between the links off), so rapier keeps every
//! locked direction exact and computes the joint-space dynamics of all links together, with
//! gravity (-Z) on each link's own mass. rapier's built-in joint motors are not used (NOTES:
//! they are implicit PD without integral action); the drive forces come from our drive models.
//!
//! Two rates. The stiff drive dynamics (screw spring, friction bristles, current loop) need the
//! fine plant step `h`; the multibody's own dynamics (its joint-space mass matrix `M(q)` and its
//! bias forces: gravity, Coriolis) change only with the configuration, slowly. So:
//!
//! - every fine step `h` the motor sides and the carriages' joint coordinates advance by
//!   semi-implicit Euler, the reduced plant's integrator: `v += h (M⁻¹ f + b)`, `q += h v`,
//!   with `f` the net drive forces (screw force minus guideway friction, along each joint),
//!   `M⁻¹` and the bias acceleration `b` frozen over the macro step;
//! - every macro step `H` (about [`MULTIBODY_STEP_S`], a whole number of fine steps) rapier
//!   advances the multibody by `H` under the mean drive force of those fine steps (the same
//!   impulse). Its joint velocities become the carriages' velocities; `M⁻¹` is refreshed from
//!   its factorised mass matrix and `b` from what it did, `b = (v⁺ - v)/H - M⁻¹ f̄`. The
//!   joint coordinates integrated at the fine step are written back into the multibody (its
//!   forward kinematics places the links): rapier's own position update at `H`,
//!   `q += H v⁺`, is off by `H/2` times the change of velocity over the step (micrometres
//!   along a circle at 1 ms), while the fine integration is the reduced plant's.
//!
//! The stability of the scheme is that of the fine integration (checked by
//! `DriveParams::largest_stable_step_s` against `h`): the macro step only carries impulses,
//! there are no stiff terms in the multibody itself (no contacts, no joint springs or motors).
//! With `M` and `b` constant, as for orthogonal prismatic chains, the carriages follow the
//! reduced plant's equations to rounding.

use super::{AxisLayout, Plant, PlantError};
use rapier3d_f64::prelude::*;
use vmt_model::drive::{AxisCommand, CarriageState, Drive};

/// The target macro step of the multibody, s: rapier advances the links every
/// `round(MULTIBODY_STEP_S / h)` fine plant steps (at least one).
pub const MULTIBODY_STEP_S: f64 = 1e-3;

/// One link: its rigid body and joint, and the guideway friction state.
#[derive(Clone, Debug)]
struct Link {
    body: RigidBodyHandle,
    joint: MultibodyJointHandle,
    carriage: CarriageState,
    /// Axis coordinate at joint coordinate 0, m.
    q0: f64,
    sign: f64,
    direction: Vector,
}

/// rapier3d multibody of the moving assemblies, driven by our drive models.
pub struct MultibodyPlant {
    world: PhysicsWorld,
    links: [Link; 3],
    drives: [Drive; 3],
    /// Joint-space inverse mass in axis coordinates (`[i][j]`: acceleration of axis i per
    /// newton on axis j), 1/kg, frozen over a macro step.
    inv_mass: [[f64; 3]; 3],
    /// Bias acceleration of each axis (gravity, Coriolis), m/s², frozen over a macro step.
    bias_m_s2: [f64; 3],
    /// Fine steps per macro step.
    fine_per_macro: usize,
    /// Fine steps, time (s) and impulse of the drive forces (N·s, axis coordinates) since the
    /// last macro step.
    fine_done: usize,
    elapsed_s: f64,
    impulse_n_s: [f64; 3],
    /// Macro steps rapier has taken since the plant was built.
    macro_steps: u64,
    /// Process force along each axis (axis coordinates), N.
    process_n: [f64; 3],
}

impl MultibodyPlant {
    /// A plant at rest, each carriage where its drive's motor is, links with the own masses of
    /// `layout`, stepped by `h` seconds.
    pub fn new(drives: [Drive; 3], layout: &[AxisLayout; 3], h: f64) -> Result<Self, PlantError> {
        let mut world = PhysicsWorld::new();
        world.gravity = Vector::new(0.0, 0.0, -super::GRAVITY_M_S2);
        world.integration_parameters.dt = h;
        // One solver pass per step: the soft-TGS solver would otherwise split each step into
        // substeps with our forces held, a different integrator from the motor side's.
        world.integration_parameters.num_solver_iterations = 1;
        // No colliders and no constraints beyond the reduced-coordinate joints: the position
        // stabilisation pass and CCD have nothing to do but cost time every step (a 64 s run
        // gave the same carriage positions to 1e-12 m without them, and ~10 % faster).
        let p = &mut world.integration_parameters;
        p.num_internal_stabilization_iterations = 0;
        p.max_ccd_substeps = 0;
        let ground = world.bodies.insert(RigidBodyBuilder::fixed().build());
        // Insert parents before children: an axis' parent is nearer the ground.
        let mut order: Vec<usize> = (0..3).collect();
        order.sort_by_key(|&i| depth(layout, i));
        let mut built: Vec<(usize, Link)> = Vec::new();
        for i in order {
            let l = &layout[i];
            let direction = Vector::ith(i, 1.0);
            let q0 = drives[i].motor_position_m;
            let mass =
                MassProperties::new(Vector::ZERO, l.link_mass_kg, Vector::splat(l.link_mass_kg));
            let body = world.bodies.insert(
                RigidBodyBuilder::dynamic()
                    .additional_mass_properties(mass)
                    .build(),
            );
            let parent = match l.parent {
                Some(p) => built
                    .iter()
                    .find(|(k, _)| *k == p.index())
                    .map_or(ground, |(_, b)| b.body),
                None => ground,
            };
            // The joint's origin is the start position, so its coordinate is the travel from it.
            let joint = PrismaticJointBuilder::new(direction)
                .local_anchor1(direction * (l.sign * q0))
                .contacts_enabled(false);
            let joint = world
                .multibody_joints
                .insert(parent, body, joint, true)
                .ok_or(PlantError::Joint(l.axis))?;
            let carriage = CarriageState {
                position_m: q0,
                ..Default::default()
            };
            built.push((
                i,
                Link {
                    body,
                    joint,
                    carriage,
                    q0,
                    sign: l.sign,
                    direction,
                },
            ));
        }
        built.sort_by_key(|(i, _)| *i);
        let links: [Link; 3] = match built
            .into_iter()
            .map(|(_, l)| l)
            .collect::<Vec<_>>()
            .try_into()
        {
            Ok(links) => links,
            Err(_) => return Err(PlantError::Joint(layout[0].axis)),
        };
        // Until rapier has taken its first step: the moving masses and gravity of the layout
        // (the joint-space dynamics of orthogonal prismatic chains).
        let mut inv_mass = [[0.0; 3]; 3];
        for (i, row) in inv_mass.iter_mut().enumerate() {
            row[i] = 1.0 / layout[i].moving_mass_kg;
        }
        let bias_m_s2 = std::array::from_fn(|i| layout[i].gravity_n / layout[i].moving_mass_kg);
        let fine_per_macro = ((MULTIBODY_STEP_S / h).round() as usize).max(1);
        let mut plant = Self {
            world,
            links,
            drives,
            inv_mass,
            bias_m_s2,
            fine_per_macro,
            fine_done: 0,
            elapsed_s: 0.0,
            impulse_n_s: [0.0; 3],
            macro_steps: 0,
            process_n: [0.0; 3],
        };
        let (q, v) = plant.read_joints();
        for (l, (q, v)) in plant.links.iter_mut().zip(q.into_iter().zip(v)) {
            l.carriage.position_m = q;
            l.carriage.velocity_m_s = v;
        }
        Ok(plant)
    }

    /// How many macro steps rapier has advanced the multibody since the plant was built.
    pub fn macro_steps(&self) -> u64 {
        self.macro_steps
    }

    /// The joint-space dynamics rapier gave at its last macro step, in axis coordinates: the
    /// inverse mass (1/kg; `[i][j]` is the acceleration of axis i per newton on axis j) from its
    /// factorised mass matrix, and the bias acceleration of each axis (m/s²; gravity,
    /// Coriolis) from the velocities it reached. These are what the fine steps use until the
    /// next macro step. `None` before rapier's first step (the fine steps then use the
    /// layout's moving masses and gravity).
    pub fn rapier_dynamics(&self) -> Option<([[f64; 3]; 3], [f64; 3])> {
        (self.macro_steps > 0).then_some((self.inv_mass, self.bias_m_s2))
    }

    /// The translation (m) of the rigid body of each axis' link (X, Y, Z) in the machine frame,
    /// as rapier's rigid-body set holds it: placed by the multibody's forward kinematics at the
    /// last macro step, at the carriages' positions (before rapier's first step the bodies are
    /// where they were built, at the origin). A workpiece-side link moves along `-q` and
    /// carries the links outboard of it.
    pub fn link_translations_m(&self) -> [[f64; 3]; 3] {
        std::array::from_fn(|i| {
            self.world
                .bodies
                .get(self.links[i].body)
                .map_or([f64::NAN; 3], |b| {
                    let t = b.translation();
                    [t.x, t.y, t.z]
                })
        })
    }

    /// Each link's coordinate (m) and velocity (m/s) in the multibody, in axis coordinates.
    fn read_joints(&self) -> ([f64; 3], [f64; 3]) {
        let (mut q, mut v) = ([0.0; 3], [0.0; 3]);
        for (i, link) in self.links.iter().enumerate() {
            if let Some((mb, id)) = self.world.multibody_joints.get(link.joint)
                && let Some(l) = mb.link(id)
            {
                q[i] = link.q0 + link.sign * l.joint().coords()[0];
                v[i] = link.sign * mb.joint_velocity(l)[0];
            }
        }
        (q, v)
    }

    /// One macro step: rapier advances the multibody by the time since the last one under the
    /// mean drive forces; the carriages take its velocities, it takes their positions, and the
    /// inverse mass and bias are refreshed.
    fn macro_step(&mut self) {
        let big_h = self.elapsed_s;
        let mean = self.impulse_n_s.map(|j| j / big_h);
        let (_, v0) = self.read_joints();
        for (l, f) in self.links.iter().zip(mean) {
            if let Some(body) = self.world.bodies.get_mut(l.body) {
                body.reset_forces(false);
                body.add_force(l.direction * (l.sign * f), true);
            }
        }
        self.world.integration_parameters.dt = big_h;
        self.world.step();
        self.macro_steps += 1;
        let (q1, v1) = self.read_joints();
        // The inverse mass matrix rapier factorised for this step, in axis coordinates.
        let mut inv_mass = [[0.0; 3]; 3];
        for (i, li) in self.links.iter().enumerate() {
            for (j, lj) in self.links.iter().enumerate() {
                let (Some((mb, a)), Some((mb2, b))) = (
                    self.world.multibody_joints.get(li.joint),
                    self.world.multibody_joints.get(lj.joint),
                ) else {
                    continue;
                };
                if !std::ptr::eq(mb, mb2) {
                    continue;
                }
                let (Some(la), Some(lb)) = (mb.link(a), mb.link(b)) else {
                    continue;
                };
                let mut e = rapier3d_f64::na::DVector::zeros(mb.ndofs());
                e[lb.assembly_id()] = 1.0;
                if mb.inv_augmented_mass().solve_mut(&mut e) {
                    inv_mass[i][j] = li.sign * lj.sign * e[la.assembly_id()];
                }
            }
        }
        self.inv_mass = inv_mass;
        for i in 0..3 {
            let pushed: f64 = (0..3).map(|j| inv_mass[i][j] * mean[j]).sum();
            self.bias_m_s2[i] = (v1[i] - v0[i]) / big_h - pushed;
        }
        // Positions from the fine integration back into the multibody.
        for (i, l) in self.links.iter_mut().enumerate() {
            l.carriage.velocity_m_s = v1[i];
            if let Some((mb, id)) = self.world.multibody_joints.get_mut(l.joint) {
                let dof = mb.link(id).map_or(0, |k| k.assembly_id());
                let mut disp = vec![0.0; mb.ndofs()];
                disp[dof] = l.sign * (l.carriage.position_m - q1[i]);
                mb.apply_displacements(&disp);
                mb.forward_kinematics(&self.world.bodies, false);
                mb.update_rigid_bodies(&mut self.world.bodies, false);
            }
        }
        self.fine_done = 0;
        self.elapsed_s = 0.0;
        self.impulse_n_s = [0.0; 3];
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

impl Plant for MultibodyPlant {
    fn control(&mut self, commands: &[AxisCommand; 3], period_s: f64) {
        for ((d, c), l) in self.drives.iter_mut().zip(commands).zip(&self.links) {
            d.control(c, l.carriage.position_m, period_s);
        }
    }

    fn step(&mut self, h: f64) {
        let [d0, d1, d2] = self.drives.each_mut();
        let [l0, l1, l2] = self.links.each_mut();
        let axes = [
            (d0, &mut l0.carriage),
            (d1, &mut l1.carriage),
            (d2, &mut l2.carriage),
        ];
        let net = Drive::step_all(axes, self.process_n, h);
        for (i, l) in self.links.iter_mut().enumerate() {
            let m = &self.inv_mass[i];
            let a = m[0] * net[0] + m[1] * net[1] + m[2] * net[2] + self.bias_m_s2[i];
            l.carriage.velocity_m_s += h * a;
            l.carriage.position_m += h * l.carriage.velocity_m_s;
            self.impulse_n_s[i] += h * net[i];
        }
        self.elapsed_s += h;
        self.fine_done += 1;
        if self.fine_done >= self.fine_per_macro {
            self.macro_step();
        }
    }

    fn drive(&self, i: usize) -> &Drive {
        &self.drives[i]
    }

    fn carriages(&self) -> [CarriageState; 3] {
        std::array::from_fn(|i| self.links[i].carriage)
    }

    fn set_tool_force(&mut self, force_n: nalgebra::Vector3<f64>) {
        self.process_n = [force_n.x, force_n.y, force_n.z];
    }
}
