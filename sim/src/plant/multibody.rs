//! The multibody plant: the carriages as links of a rapier3d-f64 multibody.
//!
//! The ground is a fixed body; each side of the topology is a chain of prismatic multibody
//! joints from the ground outwards (contacts between the links off), so rapier keeps every
//! locked direction exact and integrates the free coordinates of all links together, with
//! gravity (-Z) on each link's own mass. Every step we apply to each link the net force of its
//! drive along its axis (screw force minus guideway friction, our models) and let rapier advance
//! the multibody by the same step `h`; the motor sides are advanced by our drive model.
//! rapier's built-in joint motors are not used (NOTES: they are implicit PD without integral
//! action).

use super::{AxisLayout, Plant, PlantError};
use rapier3d_f64::prelude::*;
use vmt_model::drive::{AxisCommand, CarriageState, Drive, carriage_force};

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
        let mut plant = Self {
            world,
            links,
            drives,
        };
        plant.read_carriages();
        Ok(plant)
    }

    /// Reads each link's coordinate and velocity from the multibody, in axis coordinates.
    fn read_carriages(&mut self) {
        for link in &mut self.links {
            if let Some((mb, id)) = self.world.multibody_joints.get(link.joint)
                && let Some(l) = mb.link(id)
            {
                link.carriage.position_m = link.q0 + link.sign * l.joint().coords()[0];
                link.carriage.velocity_m_s = link.sign * mb.joint_velocity(l)[0];
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

impl Plant for MultibodyPlant {
    fn control(&mut self, commands: &[AxisCommand; 3], period_s: f64) {
        for ((d, c), l) in self.drives.iter_mut().zip(commands).zip(&self.links) {
            d.control(c, l.carriage.position_m, period_s);
        }
    }

    fn step(&mut self, h: f64) {
        for (d, l) in self.drives.iter_mut().zip(&mut self.links) {
            let screw = d.screw_force(&l.carriage);
            let net = carriage_force(&d.params, &mut l.carriage, screw, 0.0, h);
            if let Some(body) = self.world.bodies.get_mut(l.body) {
                body.reset_forces(false);
                body.add_force(l.direction * (l.sign * net), true);
            }
            d.step_motor(h, screw);
        }
        self.world.integration_parameters.dt = h;
        self.world.step();
        self.read_carriages();
    }

    fn drive(&self, i: usize) -> &Drive {
        &self.drives[i]
    }

    fn carriages(&self) -> [CarriageState; 3] {
        std::array::from_fn(|i| self.links[i].carriage)
    }
}
