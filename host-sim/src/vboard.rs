//! The virtual board: the same `hydra_core` runtime and protocol handler as the firmware,
//! against the simulated tangent axis of the reference machine (`shared/PLANT.md`).
//!
//! | board | virtual board |
//! |---|---|
//! | encoder timers, DAC | plant ([`crate::plant`]) sampled through the scenario's encoders; the DAC code is applied one period after its sample |
//! | `Runtime<Follower<1, N>, 1, 0>` tick | the same, once per simulated period |
//! | USART + DMA | a pseudo-terminal (`host-sim serve --pty`) |
//! | two flash sectors | [`RamFlash`] (in memory: lost when the process ends) |
//!
//! Units: table master in master counts = mdeg of the rotary table (encoder 0.001°),
//! slave positions in µm (encoder 1 µm per count). The master rotates through the
//! scenario's profile from the first `Start` on; before that it rests at its start angle.
//! A motion command is answered after the tick that applies it (the firmware's UART task
//! likewise waits for the tick's reply).

use crate::plant::sensors::dac_to_unit;
use crate::plant::{HydraulicAxis, MasterProfile};
use crate::scenario::Scenario;
use hydra_core::axis::AxisConfig;
use hydra_core::follower::{Follower, FollowerConfig};
use hydra_core::protocol::msg::{AxisSample, StatusMsg, Telemetry};
use hydra_core::protocol::ramflash::RamFlash;
use hydra_core::protocol::report::{
    command_nak, fill_status, motion_command, refused, state_code, REFUSED_LAW, REFUSED_NOT_SAFE,
};
use hydra_core::protocol::{
    apply_param, apply_saved_set, reference_offset_um, Device, Handler, Motion, Nak, NakCode,
    ParamId, ParamRecord, Store,
};
use hydra_core::runtime::{
    BootCause, Command, CommandError, EncoderSample, Runtime, RuntimeConfig, Sample, State,
};
use hydra_core::table::{AxisLimits, CamTable, TableLimits};
use hydra_core::units::{Counts, MasterRate, PosUm, PressureBar, VelUmPerS};

/// Table capacity of the virtual board, rows: the board's (`hydra_core::profile`), so a
/// table the board would refuse is refused here too.
pub const CAPACITY: usize = hydra_core::profile::TABLE_NODES;
/// Slave axes (the tangent cylinder).
pub const AXES: usize = 1;
/// Flash slot size, bytes (covers 256 rows of 12 bytes and every parameter record).
pub const SLOT_BYTES: u32 = 8 * 1024;
/// Firmware version reported by Info.
pub const FIRMWARE: [u8; 3] = [0, 1, 0];

/// The law, on the heap: built in place (`Follower::unconfigured` → `configure` →
/// `load_table`) and installed by moving the pointer, as the firmware swaps references.
type Law = Box<Follower<AXES, CAPACITY>>;

/// The simulated machine plus the runtime: the protocol's [`Device`].
pub struct Machine {
    rt: Runtime<Law, AXES, 0>,
    fcfg: FollowerConfig<AXES>,
    limits: TableLimits<AXES>,
    /// The boot configuration (`fcfg`, `limits` before any SetParam).
    boot: (FollowerConfig<AXES>, TableLimits<AXES>),
    plant: HydraulicAxis,
    master: MasterProfile,
    master_res_deg: f64,
    step_s: f64,
    steps: u32,
    period_s: f64,
    /// Master time, s (advances once started).
    t_master: f64,
    started: bool,
    dac: hydra_core::units::DacCode,
    enc_um: f64,
}

impl Machine {
    /// The tangent axis of `scn` (its first follower axis) with the reference gains.
    pub fn new(scn: &Scenario) -> anyhow::Result<Self> {
        let ax = scn
            .axes
            .first()
            .ok_or_else(|| anyhow::anyhow!("the scenario has no axis"))?;
        let x0_mm = ax.x0_mm.unwrap_or(250.0);
        let plant = ax.plant(scn.supply(), x0_mm * 1e-3);
        // No-load speeds at full opening, measured on the plant itself (0.3 s open loop).
        let speed = |u: f64| {
            let mut p = plant.clone();
            for _ in 0..(0.3 / scn.step_s()) as usize {
                p.step(u, scn.step_s());
            }
            p.v_m_per_s().abs() * 1e6
        };
        let (v_ext, v_ret) = (speed(1.0), speed(-1.0));
        let period_us = scn.sim.period_us;
        // Velocity feed-forward from the no-load speeds: full DAC range at full speed.
        let axis = AxisConfig {
            kp_lsb_per_um: 0.2,
            kv_pos_lsb_per_um_s: (2047.0 / v_ext) as f32,
            kv_neg_lsb_per_um_s: (2047.0 / v_ret) as f32,
            following_error_um: 20_000.0,
            ..AxisConfig::default()
        };
        let fcfg = FollowerConfig {
            period_us,
            axes: [axis],
            ..FollowerConfig::default()
        };
        let rcfg = RuntimeConfig::<AXES> {
            period_us,
            following_error_limit_um: [20_000.0],
            master_max_speed_counts_per_s: 100_000.0,
            slave_max_speed_um_per_s: [2_000_000.0],
            ..RuntimeConfig::default()
        };
        let rcoeffs = rcfg
            .build()
            .map_err(|e| anyhow::anyhow!("runtime config: {e:?}"))?;
        let limits = TableLimits {
            // 3 °/s nominal + 3 % ripple, with margin: 5 °/s = 5000 mdeg/s.
            master_speed_per_s: MasterRate::from_num(5000),
            axes: [AxisLimits {
                min_um: PosUm::from_num(0),
                max_um: PosUm::from_num(ax.cylinder.stroke_mm * 1000.0),
                max_speed_um_per_s: VelUmPerS::from_num(v_ext.min(v_ret)),
            }],
        };
        Ok(Self {
            rt: Runtime::new(rcoeffs, None, BootCause::Normal),
            fcfg,
            limits,
            boot: (fcfg, limits),
            plant,
            master: scn.master_profile()?,
            master_res_deg: scn.master.resolution_deg,
            step_s: scn.step_s(),
            steps: scn.steps_per_period(),
            period_s: scn.period_s(),
            t_master: 0.0,
            started: false,
            dac: hydra_core::units::DacCode::NULL,
            enc_um: ax.sensors.encoder_um,
        })
    }

    /// Control period, s.
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// The runtime.
    pub fn runtime(&self) -> &Runtime<Law, AXES, 0> {
        &self.rt
    }

    fn sample(&self) -> Sample<AXES, 0> {
        let deg = self.master.angle_deg(self.t_master);
        let m = (deg / self.master_res_deg).round() as i32;
        let x = (self.plant.x_m() * 1e6 / self.enc_um).round() as i32;
        Sample {
            enc: EncoderSample {
                master: Counts(m),
                slaves: [Counts(x)],
            },
            pressure_bar: [PressureBar::ZERO; 0],
            estop: false,
            overrun: false,
        }
    }

    /// One control period: sample, runtime step (with `cmd`), then the plant runs the
    /// period with the previous period's DAC code (one period of computation delay).
    pub fn tick(&mut self, cmd: Option<Command>) -> Option<Result<(), CommandError>> {
        let s = self.sample();
        let t0 = std::time::Instant::now();
        let out = self.rt.step(&s, cmd);
        let ns = u32::try_from(t0.elapsed().as_nanos()).unwrap_or(u32::MAX);
        self.rt.record_tick_cycles(ns);
        let u = dac_to_unit(self.dac);
        for _ in 0..self.steps {
            self.plant.step(u, self.step_s);
        }
        self.dac = if out.enable {
            out.dac[0]
        } else {
            self.rt.null_codes()[0]
        };
        if self.started {
            self.t_master += self.period_s;
        }
        out.reply
    }

    /// The telemetry sample of the last tick.
    pub fn telemetry(&self) -> Telemetry {
        let st = self.rt.status();
        let mut t = Telemetry {
            tick: st.tick,
            master: st.master.to_bits(),
            axes: heapless::Vec::new(),
        };
        for i in 0..AXES {
            let _ = t.axes.push(AxisSample {
                target_um: st.target_um[i].to_bits(),
                actual_um: st.pos_um[i].to_bits(),
                dac: st.dac[i].get(),
            });
        }
        t
    }
}

/// A law for `table` with `cfg`, built in place on the heap.
fn build_law(
    cfg: &FollowerConfig<AXES>,
    table: &CamTable<AXES, CAPACITY>,
) -> Result<Law, hydra_core::follower::FollowerError> {
    let mut f: Law = Box::new(Follower::unconfigured());
    f.configure(cfg)?;
    f.load_table(table);
    Ok(f)
}

impl Device<AXES, CAPACITY> for Machine {
    fn firmware(&self) -> [u8; 3] {
        FIRMWARE
    }
    fn period_us(&self) -> u32 {
        self.fcfg.period_us
    }
    fn table_limits(&self) -> TableLimits<AXES> {
        self.limits
    }
    fn active_table(&self) -> Option<&CamTable<AXES, CAPACITY>> {
        self.rt.law().map(|l| l.table())
    }
    fn at_safe_point(&self) -> bool {
        self.rt.at_safe_point()
    }
    fn all_idle(&self) -> bool {
        matches!(self.rt.state(), State::Idle | State::Fault)
    }
    fn install_table(&mut self, table: &CamTable<AXES, CAPACITY>) -> Result<(), Nak> {
        let f = build_law(&self.fcfg, table).map_err(|_| refused(REFUSED_LAW))?;
        // at_safe_point() was checked by the handler, so Busy would be a handler bug.
        self.rt
            .install(f)
            .map(|_| ())
            .map_err(|_| refused(REFUSED_NOT_SAFE))
    }
    fn command(&mut self, m: Motion) -> Result<(), Nak> {
        let cmd = motion_command(m);
        let state = state_code(self.rt.state());
        match self.tick(Some(cmd)) {
            Some(Err(e)) => Err(command_nak(state, e)),
            _ => {
                if m == Motion::Start {
                    self.started = true;
                }
                Ok(())
            }
        }
    }
    fn persisted_offset_um(&self, axis: u8) -> Option<f32> {
        self.rt.absolute_offset_um(axis).map(|o| o.to_num())
    }
    fn set_param(&mut self, axis: u8, param: ParamId, value: f32) -> Result<(), Nak> {
        let range = Nak::with(NakCode::ParamRange, u16::from(axis), param as u8);
        if param == ParamId::SlaveOffsetUm {
            let off = reference_offset_um(axis, value)?;
            return self
                .rt
                .restore_reference_offset(axis, off)
                .map_err(|_| range);
        }
        if !self.all_idle() {
            return Err(Nak::new(NakCode::NotIdle));
        }
        let mut f = self.fcfg;
        let mut lim = self.limits;
        let active = self.rt.law().map(|l| l.table());
        apply_param(&mut f, &mut lim, active, axis, param, value)?;
        // Rebuild the law if one runs.
        if let Some(t) = self.rt.law().map(|l| l.table()) {
            let law = build_law(&f, t).map_err(|_| range)?;
            self.rt
                .install(law)
                .map_err(|_| Nak::new(NakCode::NotIdle))?;
        }
        self.fcfg = f;
        self.limits = lim;
        Ok(())
    }
    fn set_params(&mut self, records: &[ParamRecord]) -> Result<(), Nak> {
        // Boot only: the whole set on copies, kept only if all of it is valid.
        if self.rt.law().is_some() {
            return Err(Nak::new(NakCode::NotIdle));
        }
        let (mut f, mut lim) = (self.fcfg, self.limits);
        let mut offsets = [None; AXES];
        apply_saved_set::<AXES, CAPACITY>(&mut f, &mut lim, &mut offsets, records)?;
        for (axis, off) in (0u8..).zip(offsets) {
            if let Some(o) = off {
                let range = Nak::with(
                    NakCode::ParamRange,
                    u16::from(axis),
                    ParamId::SlaveOffsetUm as u8,
                );
                self.rt
                    .restore_reference_offset(axis, o)
                    .map_err(|_| range)?;
            }
        }
        (self.fcfg, self.limits) = (f, lim);
        Ok(())
    }
    fn reset_params(&mut self) -> Result<(), Nak> {
        if self.rt.law().is_some() {
            return Err(Nak::new(NakCode::NotIdle));
        }
        (self.fcfg, self.limits) = self.boot;
        // A refused slot's restored reference offsets go too.
        for axis in 0..AXES as u8 {
            let _ = self.rt.restore_reference_offset(axis, PosUm::ZERO);
        }
        Ok(())
    }
    fn status(&self, out: &mut StatusMsg) {
        // The simulation has no CPU clock: its timing fields are 0 (reported as is).
        fill_status(self.rt.status(), |c| c, out);
    }
}

/// The whole virtual board: machine, protocol handler and flash.
pub struct VBoard {
    /// The machine.
    pub machine: Machine,
    /// The protocol handler.
    pub handler: Handler<AXES, CAPACITY>,
    /// The flash (two slots).
    pub flash: RamFlash,
}

impl VBoard {
    /// A board on the reference tangent scenario, booted from an empty flash.
    pub fn new(scn: &Scenario) -> anyhow::Result<Self> {
        Self::with_flash(scn, RamFlash::new(2 * SLOT_BYTES as usize))
    }

    /// A board booted from `flash` (e.g. another board's flash after a Save: a power
    /// cycle). `flash` must be at least two slots ([`SLOT_BYTES`] each).
    pub fn with_flash(scn: &Scenario, flash: RamFlash) -> anyhow::Result<Self> {
        let mut machine = Machine::new(scn)?;
        let store = Store::new::<_, AXES, CAPACITY>(&flash, 0, SLOT_BYTES)
            .map_err(|e| anyhow::anyhow!("flash geometry: {e:?}"))?;
        let mut handler = Handler::new(store);
        let mut flash = flash;
        handler.boot(&mut machine, &mut flash);
        Ok(Self {
            machine,
            handler,
            flash,
        })
    }

    /// A board booted from the flash image in `path` (created erased if the file does
    /// not exist): with [`VBoard::persist`] after every request, restarting the process
    /// is a power cycle of the board.
    pub fn with_flash_file(scn: &Scenario, path: &std::path::Path) -> anyhow::Result<Self> {
        let size = 2 * SLOT_BYTES as usize;
        let mut flash = RamFlash::new(size);
        match std::fs::read(path) {
            Ok(img) if img.len() == size => flash.mem = img,
            Ok(img) => anyhow::bail!(
                "{}: a flash image of {} bytes, expected {size} (two slots of {SLOT_BYTES})",
                path.display(),
                img.len()
            ),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => anyhow::bail!("{}: {e}", path.display()),
        }
        Self::with_flash(scn, flash)
    }

    /// Writes the flash image to `path` if it changed since `*seen_ops` (the flash's
    /// operation count): to a temporary file, then renamed over the old one, so a crash
    /// of the host never leaves half an image (the board's own power-cut safety is the
    /// store's, inside the image).
    pub fn persist(&self, path: &std::path::Path, seen_ops: &mut usize) -> anyhow::Result<()> {
        if self.flash.ops == *seen_ops {
            return Ok(());
        }
        let tmp = path.with_extension("tmp");
        std::fs::write(&tmp, &self.flash.mem)?;
        std::fs::rename(&tmp, path)?;
        *seen_ops = self.flash.ops;
        Ok(())
    }

    /// Received bytes → responses through `tx`.
    pub fn on_bytes(&mut self, bytes: &[u8], tx: &mut impl FnMut(&[u8])) {
        self.handler
            .on_bytes(&mut self.machine, &mut self.flash, bytes, tx);
    }

    /// One control period, with telemetry through `tx` when due.
    pub fn tick(&mut self, tx: &mut impl FnMut(&[u8])) {
        self.machine.tick(None);
        // A refused deferred activation keeps the running table; Status shows the id.
        let _ = self.handler.poll(&mut self.machine);
        // The host-link watchdog on the board's own clock (ticks × period).
        let ms = u64::from(self.machine.runtime().status().tick)
            * u64::from(self.machine.runtime().coeffs().period_us)
            / 1000;
        self.handler.watch_link(&mut self.machine, ms as u32);
        let m = &self.machine;
        self.handler.on_tick(tx, || m.telemetry());
    }
}
