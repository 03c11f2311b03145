//! The simulated head: servo positions that follow the commanded trajectories
//! ([`hvs_shared::runtime::trajectory::GazeController`], whole 0.18 degree steps, within the
//! limits) on the control clock, sampled at the camera frames.

use hvs_shared::runtime::gaze::Joints;
use hvs_shared::runtime::trajectory::{ControllerConfig, GazeController};

/// A head whose servos are exactly at the controller's setpoints.
#[derive(Debug, Clone)]
pub struct VirtualHead {
    controller: GazeController,
    hz: u32,
    ticks: u64,
    goal: Option<Joints>,
}

impl VirtualHead {
    /// A head at rest at home.
    pub fn new(cfg: &ControllerConfig) -> anyhow::Result<VirtualHead> {
        Ok(VirtualHead {
            controller: GazeController::new(cfg)
                .map_err(|e| anyhow::anyhow!("head controller: {e:?}"))?,
            hz: cfg.control_hz,
            ticks: 0,
            goal: None,
        })
    }

    /// Runs the control ticks up to time `t_s` (s since start).
    pub fn advance_to(&mut self, t_s: f64) {
        while ((self.ticks + 1) as f64) / f64::from(self.hz) <= t_s + 1e-9 {
            self.controller.tick();
            self.ticks += 1;
        }
    }

    /// Commands a new goal (a repeated goal does not re-plan the move).
    pub fn command(&mut self, goal: &Joints) {
        if self.goal != Some(*goal) {
            self.controller.start(goal);
            self.goal = Some(*goal);
        }
    }

    /// Where the servos are (degrees).
    pub fn joints(&self) -> Joints {
        self.controller.setpoint()
    }

    /// Whether a move is still under way (the controller's trajectories have not ended).
    pub fn is_moving(&self) -> bool {
        self.controller.is_moving()
    }

    /// Control ticks per second.
    pub fn control_hz(&self) -> u32 {
        self.hz
    }

    /// The time of the control clock (s).
    pub fn time_s(&self) -> f64 {
        self.ticks as f64 / f64::from(self.hz)
    }
}
