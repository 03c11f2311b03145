//! The virtual head of `hvs track`, `hvs collect` and `hvs view`: the simulated head
//! ([`crate::sim::head::SimHead`]: the firmware's loop step, servos at the controller's setpoints,
//! every safety rule checked on every tick), commanded with joint targets and sampled at the
//! camera frames.

use crate::sim::head::SimHead;
use anyhow::{anyhow, Result};
use hvs_shared::runtime::gaze::{GazeConfig, Joints};
use hvs_shared::runtime::head;
use hvs_shared::runtime::protocol::{Request, RequestBody};
use hvs_shared::runtime::trajectory::ControllerConfig;

/// A head whose servos are exactly at the controller's setpoints.
#[derive(Debug, Clone)]
pub struct VirtualHead {
    sim: SimHead,
    hz: u32,
    goal: Option<Joints>,
}

impl VirtualHead {
    /// A head at rest at home, its loop armed (its servos commanded on every tick).
    pub fn new(cfg: &ControllerConfig) -> Result<VirtualHead> {
        let gaze = GazeConfig { limits: cfg.limits, ..GazeConfig::DEFAULT };
        let mut sim = SimHead::new(head::boot(&[], &[]), gaze, cfg)
            .map_err(|e| anyhow!("head controller: {e:?}"))?;
        sim.request(&Request { id: 1, body: RequestBody::Home })
            .map_err(|v| anyhow!("the virtual head: {v}"))?;
        Ok(VirtualHead { sim, hz: cfg.control_hz, goal: None })
    }

    /// Runs the control ticks up to time `t_s` (s since start). Fails if a tick breaks a
    /// safety rule (a setpoint off the limits or the step grid, a jump, a servo command
    /// beyond the limits).
    pub fn advance_to(&mut self, t_s: f64) -> Result<()> {
        while ((self.sim.ticks + 1) as f64) / f64::from(self.hz) <= t_s + 1e-9 {
            self.sim.tick(1).map_err(|v| anyhow!("the virtual head: {v}"))?;
        }
        Ok(())
    }

    /// Commands a new goal (a repeated goal does not re-plan the move).
    pub fn command(&mut self, goal: &Joints) {
        if self.goal != Some(*goal) {
            self.sim.head.controller.start(goal);
            self.goal = Some(*goal);
        }
    }

    /// Where the servos are (degrees).
    pub fn joints(&self) -> Joints {
        self.sim.head.joints()
    }

    /// Whether a move is still under way (the controller's trajectories have not ended).
    pub fn is_moving(&self) -> bool {
        self.sim.head.controller.is_moving()
    }

    /// Control ticks per second.
    pub fn control_hz(&self) -> u32 {
        self.hz
    }

    /// The time of the control clock (s).
    pub fn time_s(&self) -> f64 {
        self.sim.ticks as f64 / f64::from(self.hz)
    }
}
