//! A host session against the emulated board, as a machine builder runs one: boot,
//! upload the table (committed, then activated), reference the slaves (set-position at
//! their measured positions), Start, follow; and the run's report.

use crate::bus::SYSCLK_HZ;
use crate::elf::Image;
use crate::flash::Flash;
use crate::host::Host;
use crate::machine::Machine;
use crate::plant::{PlantEnv, Shared};
use anyhow::{bail, Result};
use hydra_core::protocol::msg::StatusMsg;
use hydra_core::protocol::{Request, Response};
use hydra_core::table::Node;
use hydra_core::units::{Master, PosUm};
use hydra_plant::camfile::CamCsv;
use hydra_plant::scenario::Scenario;
use std::cell::RefCell;
use std::rc::Rc;

/// Slave columns of the board's tables (`hydra_core::profile`).
pub const SLAVES: usize = hydra_core::profile::SLAVES;

/// The emulated board, its plant and a host.
pub struct Session {
    /// The board.
    pub m: Machine,
    /// The host on its USART6.
    pub host: Host,
    /// The plant's shared state.
    pub plant: Rc<RefCell<Shared>>,
    /// The table the plant measures the error against.
    pub table: CamCsv,
    /// Slave names.
    pub names: Vec<String>,
    /// Each slave's table column (mm), by its name; `None`: it holds where it stands.
    columns: Vec<Option<Vec<f64>>>,
    wall: std::time::Instant,
    image: Rc<Image>,
    scn: Scenario,
}

/// A fault's name from its code (`hydra_core::runtime::Fault::name`).
pub fn fault_name(code: u16) -> &'static str {
    hydra_core::runtime::Fault::from_code(code).map_or("unknown", |f| f.name())
}

impl Session {
    /// Powers on `image` with `flash` in the plant of `scn` following `table`.
    pub fn new(image: Rc<Image>, flash: Flash, scn: &Scenario, table: CamCsv) -> Result<Self> {
        let env = PlantEnv::new(scn, &table)?;
        let plant = env.shared.clone();
        let names = env.slaves().iter().map(|s| s.name.clone()).collect();
        let columns = (0..SLAVES)
            .map(|k| env.column(k).map(<[f64]>::to_vec))
            .collect();
        let m = Machine::new(image.clone(), flash, Box::new(env))?;
        Ok(Self {
            m,
            host: Host::new(),
            plant,
            table,
            names,
            columns,
            wall: std::time::Instant::now(),
            image,
            scn: scn.clone(),
        })
    }

    /// Cuts the board's power now and powers it on again (cold: RAM repainted, the
    /// flash as the cut left it; the plant back at rest, a new host).
    pub fn power_cycle(self) -> Result<Self> {
        let (image, scn, table) = (self.image.clone(), self.scn.clone(), self.table.clone());
        let flash = self.m.power_cut();
        Self::new(image, flash, &scn, table)
    }

    /// The table as the board's nodes: each follower slave's column by its name, and a
    /// slave without one holds where it stands.
    pub fn nodes(&self) -> Vec<Node<SLAVES>> {
        let pos = self.plant.borrow().positions_um.clone();
        (0..self.table.master.len())
            .map(|i| {
                let mut slave_um = [PosUm::ZERO; SLAVES];
                for (k, s) in slave_um.iter_mut().enumerate() {
                    let mm = self
                        .columns
                        .get(k)
                        .and_then(|c| c.as_ref())
                        .and_then(|c| c.get(i).copied());
                    let um = mm.map_or(pos.get(k).copied().unwrap_or(0.0), |v| v * 1000.0);
                    *s = PosUm::saturating_from_num(um);
                }
                Node {
                    // Master units → counts of the scenario's master encoder, as host-sim
                    // builds its table.
                    master: Master::saturating_from_num(
                        self.table.master[i] / self.scn.master.resolution_deg,
                    ),
                    slave_um,
                }
            })
            .collect()
    }

    /// Hello, then the table uploaded as `id`, committed and activated.
    pub fn upload_activate(&mut self, id: u32) -> Result<()> {
        let per = match self.host.request(&mut self.m, &Request::Hello)? {
            Response::Info(i) => usize::from(i.max_chunk_rows),
            r => bail!("Hello answered {r:?}"),
        };
        let nodes = self.nodes();
        match self.host.upload(&mut self.m, id, &nodes, per)? {
            Response::Ack { .. } => {}
            r => bail!("TableCommit answered {r:?}"),
        }
        self.host.ack(&mut self.m, &Request::Activate { id })
    }

    /// Set-position of every slave at its measured position, then Start (the master
    /// starts moving when Start is sent).
    pub fn reference_and_start(&mut self) -> Result<()> {
        let pos = self.plant.borrow().positions_um.clone();
        for (k, p) in pos.iter().enumerate().take(SLAVES) {
            let raw = (p * 256.0).round() as i32;
            self.host.ack(
                &mut self.m,
                &Request::SetPosition {
                    axis: k as u8,
                    pos_um: raw,
                },
            )?;
        }
        // A slave the plant does not have (one-axis scenarios) is referenced at 0.
        for k in pos.len()..SLAVES {
            self.host.ack(
                &mut self.m,
                &Request::SetPosition {
                    axis: k as u8,
                    pos_um: 0,
                },
            )?;
        }
        // The master starts at a tick instant, as in `host-sim run` (its master starts at
        // t = 0, a sampling instant): the next TIM7 update after now. The error figure
        // then measures the controller, not the phase of the master against the tick
        // (master quantisation alone is 12 µm per count).
        let now = self.m.cycles();
        let at = self.m.state().bus.tim7.next_event(now).unwrap_or(now);
        self.plant.borrow_mut().master_start = Some(at);
        self.host.ack(&mut self.m, &Request::Start)
    }

    /// The board's status.
    pub fn status(&mut self) -> Result<StatusMsg> {
        match self.host.request(&mut self.m, &Request::GetStatus)? {
            Response::Status(s) => Ok(s),
            r => bail!("GetStatus answered {r:?}"),
        }
    }

    /// The report of `board-emu --json`.
    pub fn report(&mut self) -> Result<serde_json::Value> {
        let st = self.status()?;
        let stats = self.m.state().stats.clone();
        let (n, sum, max) = stats.tick_cycles;
        let mut faults = Vec::new();
        if st.fault_code != 0 {
            faults.push(serde_json::json!({
                "code": st.fault_code,
                "name": fault_name(st.fault_code),
                "axis": st.fault_axis,
            }));
        }
        let mut axes = serde_json::Map::new();
        let sh = self.plant.borrow();
        for (k, name) in self.names.iter().enumerate() {
            if let Some(e) = sh.errors.get(k).filter(|e| e.n > 0) {
                axes.insert(
                    name.clone(),
                    serde_json::json!({"max_error_um": e.max, "rms_error_um": e.rms()}),
                );
            }
        }
        drop(sh);
        let log: Vec<String> = crate::rtt::decode(&self.m.image().bytes, &self.m.state().rtt)?
            .into_iter()
            .map(|l| format!("{} {}", l.level, l.message))
            .collect();
        Ok(serde_json::json!({
            "emulated_s": self.m.cycles() as f64 / SYSCLK_HZ as f64,
            "wall_s": self.wall.elapsed().as_secs_f64(),
            "ticks": n,
            "overruns": st.overruns,
            "watchdog_resets": stats.watchdog_resets,
            "tick_cycles": {"max": max, "mean": if n > 0 { sum as f64 / n as f64 } else { 0.0 }},
            "tick_instructions": {
                "max": stats.tick_instructions.1,
                "mean": if n > 0 { stats.tick_instructions.0 as f64 / n as f64 } else { 0.0 },
            },
            "boot_s": stats.first_tick.map(|c| c as f64 / SYSCLK_HZ as f64),
            "instructions": stats.instructions,
            "extended_frames": stats.extended_frames,
            "stack_min_free_bytes": self.m.stack_min_free(),
            "faults": faults,
            "axes": axes,
            "log": log,
        }))
    }
}
