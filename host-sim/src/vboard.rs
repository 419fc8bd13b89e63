//! The virtual board: the firmware's board (`hydra_core::profile`: two slaves, 256-row
//! tables, the reference gains, the runtime limits) against the simulated reference
//! machine — the tangent axis on slave 0 and the side press on slave 1
//! ([`crate::machine::MachinePlant`]). It runs core's code exactly as the firmware does:
//! the tick is core's [`TickLoop::run`] (the firmware's TIM7 handler calls the same), the
//! protocol's device is core's [`BoardDevice`] (the firmware's `device.rs` is only glue
//! too), the handler and the store are core's.
//!
//! | board (`firmware/`) | virtual board |
//! |---|---|
//! | TIM5 / TIM2 / TIM3 encoders | [`VirtualIo`] samples the plant's positions through the scenario's encoders into a [`SampledBoard`], which core's tick reads through its board traits |
//! | ADC1 chamber pressures | the plant's chamber pressures through the scenario's transducers, bar |
//! | E-stop input PE8 | [`VirtualIo::estop`] (closed unless a test opens it) |
//! | DAC1 ch 1/2 + valve enable PE7 | the codes (clamped to the board's DAC range) drive the plant's valves, 0 while unpowered; a code acts from the next period on (one period of computation delay) |
//! | DWT cycle counter | simulated time in ns plus the host's real compute time of the tick |
//! | TIM7 period, overrun flag | one tick per simulated period (never late) |
//! | SPSC queues to the link | one command slot, answered by the tick that applies it |
//! | two flash sectors | [`RamFlash`] (in memory, or in a file: `serve --flash`) |
//!
//! Units: master counts = mdeg of the rotary table (encoder 0.001°), slave positions in
//! µm (encoders 1 µm per count). The master rotates through the scenario's profile from
//! the first accepted `Start` on; before that it rests at its start angle. A motion
//! command is answered by the next tick, which applies it — the firmware's link task
//! likewise waits for the tick's reply; that tick is the next period of the simulated
//! timeline, not an extra one (`serve` paces on [`VBoard::ticks`]).

use crate::machine::MachinePlant;
use crate::plant::{valve_command, EdgeTimer};
use crate::scenario::Scenario;
use hydra_core::dac::DacRange;
use hydra_core::follower::Follower;
use hydra_core::profile;
use hydra_core::protocol::device::{BoardDevice, DeviceGlue, LawDevice};
use hydra_core::protocol::diag::{master_op, MasterStateMsg};
use hydra_core::protocol::msg::Telemetry;
use hydra_core::protocol::ramflash::RamFlash;
use hydra_core::protocol::{Handler, Nak, NakCode, Store};
use hydra_core::runtime::{
    BootCause, Capture, CaptureRow, Command, CommandError, EncoderSample, Reply, Runtime, Status,
    TickCommand, TickHost, TickLoop, TickSample,
};
use hydra_core::table::CamTable;
use hydra_core::units::{Counts, DacCode, PressureBar};
use hydra_plant::board::SampledBoard;
use std::time::Instant;

/// Slave axes: the board's.
pub const AXES: usize = profile::SLAVES;
/// Pressure inputs: the board's (A, B per slave).
pub const PRESSURES: usize = profile::PRESSURES;
/// Table capacity, rows: the board's, so a table the board would refuse is refused here.
pub const CAPACITY: usize = profile::TABLE_NODES;
/// Flash slot size, bytes (covers 256 rows of two slaves and every parameter record).
pub const SLOT_BYTES: u32 = 16 * 1024;
/// Firmware version reported by Info: the firmware crate's version of this workspace.
pub const FIRMWARE: [u8; 3] = [0, 1, 0];

/// A law buffer, on the heap: built in place (`Follower::unconfigured` → `configure` →
/// `load_table`) and installed by moving the pointer, as the firmware swaps references.
pub type Law = Box<Follower<AXES, CAPACITY>>;
/// The runtime of the virtual board.
pub type VRuntime = Runtime<Law, AXES, PRESSURES>;
type Table = CamTable<AXES, CAPACITY>;
type DeviceState = LawDevice<Law, Box<Table>, AXES, CAPACITY>;

/// The board's inputs and outputs over the plant: core's board traits.
pub struct VirtualIo {
    /// The machine.
    pub plant: MachinePlant,
    /// The E-stop chain open (stop requested).
    pub estop: bool,
    /// Master time, s (advances once started).
    pub t_master: f64,
    /// The master runs (from the first accepted Start, or `motion master start`).
    pub started: bool,
    /// The master's speed relative to the scenario's profile (`motion master --speed`).
    pub speed_scale: f64,
    master_res_deg: f64,
    /// The master encoder's edge timer (the firmware's 1 MHz one unless the scenario
    /// says otherwise), the board's time (s since power-up) and the board and master
    /// times of the last latch.
    edge_timer: Option<EdgeTimer>,
    t_board: f64,
    last_latch: Option<(f64, f64)>,
    range: DacRange,
    written: [DacCode; AXES],
    enable: bool,
    applied: [f64; AXES],
}

impl VirtualIo {
    /// The encoders latched at this tick's sample instant (the master through its edge
    /// timer between the last latch and this one).
    fn latch(&mut self) -> EncoderSample<AXES> {
        let m = (self.plant.master.angle_deg(self.t_master) / self.master_res_deg).round();
        // The master between the last latch and this one, on the board's clock (the
        // master's own time runs at `speed_scale`).
        let (t0, m0) = self.last_latch.unwrap_or((self.t_board, self.t_master));
        let (t1, m1) = (self.t_board, self.t_master);
        let rate = if t1 > t0 { (m1 - m0) / (t1 - t0) } else { 0.0 };
        let (profile, res) = (&self.plant.master, self.master_res_deg);
        let master_edges = self
            .edge_timer
            .map(|tm| tm.reading(|t| profile.angle_deg(m0 + (t - t0) * rate) / res, t0, t1));
        self.last_latch = Some((t1, m1));
        let mut slaves = [Counts(0); AXES];
        for (k, c) in slaves.iter_mut().enumerate() {
            *c = Counts(self.plant.slave_count(k) as i32);
        }
        EncoderSample {
            master: Counts(m as i32),
            slaves,
            master_edges,
        }
    }

    /// The chamber pressures, bar (A, B per slave).
    fn pressures(&self) -> [PressureBar; PRESSURES] {
        let mut p = [PressureBar::ZERO; PRESSURES];
        for (k, s) in self.plant.slaves.iter().enumerate().take(AXES) {
            let (a, b) = s.pressures_bar();
            if let Some(pair) = p.get_mut(2 * k..2 * k + 2) {
                pair[0] = PressureBar::saturating_from_num(a);
                pair[1] = PressureBar::saturating_from_num(b);
            }
        }
        p
    }

    /// The board's inputs at this tick's sample instant, for core's tick to read
    /// ([`SampledBoard`]: core's board traits, implemented once for every simulated
    /// board).
    fn sample(&mut self) -> SampledBoard<AXES, PRESSURES> {
        let mut b = SampledBoard::new(self.latch());
        b.pressure_bar = self.pressures();
        b.estop = self.estop;
        b
    }

    /// What the tick wrote: the codes, clamped to the board's DAC range as its DAC
    /// driver clamps them, and the valve power.
    fn take_outputs(&mut self, b: &SampledBoard<AXES, PRESSURES>) {
        self.written = b.codes.map(|c| self.range.clamp(c));
        self.enable = b.enable;
    }
}

impl VirtualIo {
    /// The plant runs one period (`steps` integration steps) with the codes of the
    /// previous tick; this tick's codes act from the next period on.
    fn advance(&mut self, steps: u32, period_s: f64) {
        for _ in 0..steps {
            self.plant.step(&self.applied);
        }
        for (u, c) in self.applied.iter_mut().zip(&self.written) {
            *u = valve_command(c.get(), self.enable);
        }
        self.t_board += period_s;
        if self.started {
            self.t_master += period_s * self.speed_scale;
        }
    }

    /// `motion master`: start, stop, rewind or query the simulated master
    /// ([`master_op`]), its speed scale changed unless `speed_scale` is 0 (else 0.01 …
    /// 100 of the scenario's profile).
    fn master_op(&mut self, op: u8, speed_scale: f32) -> Result<MasterStateMsg, Nak> {
        // Checked before anything changes: a refusal changes nothing.
        if op > master_op::REWIND {
            return Err(Nak::with(NakCode::NoVirtualMaster, u16::from(op), 2));
        }
        if speed_scale != 0.0 {
            if !(0.01..=100.0).contains(&speed_scale) {
                return Err(Nak::with(NakCode::NoVirtualMaster, u16::from(op), 1));
            }
            self.speed_scale = f64::from(speed_scale);
        }
        match op {
            master_op::QUERY => {}
            master_op::START => self.started = true,
            master_op::STOP => self.started = false,
            master_op::REWIND => {
                self.started = false;
                self.t_master = 0.0;
            }
            _ => return Err(Nak::with(NakCode::NoVirtualMaster, u16::from(op), 0)),
        }
        let m = &self.plant.master;
        let end_s = m.stop_time_s();
        Ok(MasterStateMsg {
            running: self.started,
            time_s: self.t_master as f32,
            position: m.angle_deg(self.t_master) as f32,
            end_s: end_s as f32,
            at_end: self.t_master >= end_s,
            speed_scale: self.speed_scale as f32,
        })
    }

    /// Whether the valve power is on (the last tick's enable).
    pub fn enabled(&self) -> bool {
        self.enable
    }
}

/// The tick's glue: a simulated clock, one command slot, the last reply and sample.
struct VHost {
    sim_ns: u64,
    wall: Instant,
    cmd: Option<TickCommand>,
    reply: Option<Reply>,
    sample: Option<TickSample<AXES>>,
    /// Samples of the ticks that answered a command (run inside the handler's call):
    /// handed to the handler's telemetry afterwards, as the firmware's link task takes
    /// every queued sample.
    command_samples: Vec<TickSample<AXES>>,
    feeds: u64,
    /// The loop-rate capture ring, as the board's ([`profile::CAPTURE_ROWS`] rows).
    capture: Capture<'static, AXES>,
}

impl TickHost<AXES, PRESSURES> for VHost {
    fn now_cycles(&mut self) -> u32 {
        // ns of simulated time at the tick's start plus the host's compute time since.
        let ns = self
            .sim_ns
            .wrapping_add(self.wall.elapsed().as_nanos() as u64);
        ns as u32
    }
    fn clear_period_flag(&mut self) {}
    fn period_flag(&mut self) -> bool {
        // The simulated clock stops while the tick runs: never late.
        false
    }
    fn take_command(&mut self) -> Option<TickCommand> {
        self.cmd.take()
    }
    fn feed_watchdog(&mut self) {
        self.feeds += 1;
    }
    fn reply(&mut self, r: Reply) {
        self.reply = Some(r);
    }
    fn status(&mut self, _st: &Status<AXES, PRESSURES>) {
        // The handler reads the runtime's status directly (`Device::status`).
    }
    fn sample(&mut self, s: &TickSample<AXES>) {
        self.capture.push(s);
        self.sample = Some(*s);
    }
}

/// The simulated machine, its board I/O and the runtime's tick: the protocol device's
/// glue ([`DeviceGlue`]).
pub struct Machine {
    tl: Option<TickLoop<Law, AXES, PRESSURES>>,
    /// The board's I/O over the plant.
    pub io: VirtualIo,
    host: VHost,
    steps: u32,
    period_s: f64,
    period_ns: u64,
    ticks: u64,
}

impl Machine {
    fn new(scn: &Scenario) -> anyhow::Result<Self> {
        let period_us = profile::PERIOD_US;
        let step_s = scn.step_s();
        let steps = (f64::from(period_us) * 1e-6 / step_s).round().max(1.0) as u32;
        Ok(Self {
            tl: None,
            io: VirtualIo {
                plant: MachinePlant::new(scn, None, AXES)?,
                estop: false,
                t_master: 0.0,
                started: false,
                speed_scale: 1.0,
                master_res_deg: scn.master.resolution_deg,
                edge_timer: scn.master_edge_timer(),
                t_board: 0.0,
                last_latch: None,
                range: profile::dac_range()
                    .ok_or_else(|| anyhow::anyhow!("the board profile's DAC range"))?,
                written: [DacCode::NULL; AXES],
                enable: false,
                applied: [0.0; AXES],
            },
            host: VHost {
                sim_ns: 0,
                wall: Instant::now(),
                cmd: None,
                reply: None,
                sample: None,
                command_samples: Vec::new(),
                feeds: 0,
                // Leaked: one ring (66 kB) per virtual board, for the life of the process.
                capture: Capture::new(
                    Vec::leak(vec![CaptureRow::ZERO; profile::CAPTURE_ROWS]),
                    Vec::leak(vec![0; profile::CAPTURE_ROWS]),
                ),
            },
            steps,
            period_s: f64::from(period_us) * 1e-6,
            period_ns: u64::from(period_us) * 1000,
            ticks: 0,
        })
    }

    /// Control period, s (the board's).
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// The runtime (`None` only during boot).
    pub fn runtime(&self) -> Option<&VRuntime> {
        self.tl.as_ref().map(TickLoop::runtime)
    }

    /// Ticks run since boot (one per simulated period).
    pub fn ticks(&self) -> u64 {
        self.ticks
    }

    /// Times the tick fed the watchdog (once per tick, as on the board).
    pub fn watchdog_feeds(&self) -> u64 {
        self.host.feeds
    }

    /// One control period: core's tick (sample → runtime → valves), then the plant runs
    /// the period. Returns the reply to a command the tick took.
    fn tick(&mut self) -> Option<Reply> {
        let tl = self.tl.as_mut()?;
        let before = tl.runtime().state();
        // The inputs are sampled before the tick starts (the simulated clock stands
        // still meanwhile): the host's compute time counted into the tick's clock is
        // the tick's own, so a host preempted while sampling the plant does not make
        // the tick look a period late.
        let mut board = self.io.sample();
        self.host.wall = Instant::now();
        tl.run(&mut board, &mut self.host);
        self.io.take_outputs(&board);
        // The simulated master runs once following starts (a Start, or the end of an
        // approach), as the machine's master would be started for a run.
        use hydra_core::runtime::State as S;
        if before != S::Following && tl.runtime().state() == S::Following {
            self.io.started = true;
        }
        self.io.advance(self.steps, self.period_s);
        self.host.sim_ns = self.host.sim_ns.wrapping_add(self.period_ns);
        self.ticks += 1;
        self.host.reply.take()
    }

    /// The telemetry sample of the last tick.
    fn telemetry(&self) -> Telemetry {
        telemetry_of(self.host.sample)
    }
}

/// A tick sample as a telemetry frame's content (none yet: an empty frame).
fn telemetry_of(sample: Option<TickSample<AXES>>) -> Telemetry {
    sample
        .as_ref()
        .map(Telemetry::of_sample)
        .unwrap_or_default()
}

impl DeviceGlue<Law, AXES, PRESSURES> for Machine {
    fn read<R>(&self, f: impl FnOnce(&VRuntime) -> R) -> Option<R> {
        self.tl.as_ref().map(|t| f(t.runtime()))
    }
    fn write<R>(&mut self, f: impl FnOnce(&mut VRuntime) -> R) -> Option<R> {
        self.tl.as_mut().map(|t| f(t.runtime_mut()))
    }
    fn command(&mut self, cmd: Command) -> Option<Result<(), CommandError>> {
        // Queued at the simulated time of the tick that takes it (the host's compute time
        // since the last tick is not simulated time): never stale.
        let queued_at = self.host.sim_ns as u32;
        self.host.cmd = Some(TickCommand {
            cmd,
            token: 0,
            queued_at,
        });
        let reply = self.tick();
        if let Some(s) = self.host.sample {
            self.host.command_samples.push(s);
        }
        let r = reply?.result.map_err(|e| e.ok_or(()));
        match r {
            Ok(()) => Some(Ok(())),
            Err(Ok(e)) => Some(Err(e)),
            // Dropped unapplied (cannot happen here: the tick takes it at once).
            Err(Err(())) => None,
        }
    }
    fn cycles_to_ns(&self, cycles: u32) -> u32 {
        // The clock counts ns.
        cycles
    }
    fn capture<R>(&mut self, f: impl FnOnce(&mut Capture<'_, AXES>) -> R) -> Option<R> {
        Some(f(&mut self.host.capture))
    }
    fn virtual_master(&mut self, op: u8, speed_scale: f32) -> Option<Result<MasterStateMsg, Nak>> {
        Some(self.io.master_op(op, speed_scale))
    }
}

/// The whole virtual board: machine, the protocol's device state, handler and flash.
pub struct VBoard {
    /// The machine.
    pub machine: Machine,
    dev: DeviceState,
    /// The protocol handler.
    pub handler: Handler<AXES, CAPACITY>,
    /// The flash (two slots).
    pub flash: RamFlash,
    /// The PLC link's server (Modbus registers → the handler's requests).
    pub plc: hydra_core::plc::Server<AXES>,
}

impl VBoard {
    /// A board on `scn`'s machine, booted from an empty flash.
    pub fn new(scn: &Scenario) -> anyhow::Result<Self> {
        Self::with_flash(scn, RamFlash::new(2 * SLOT_BYTES as usize))
    }

    /// A board booted from `flash` (e.g. another board's flash after a Save: a power
    /// cycle), as the firmware boots: the handler loads the newest valid slot and the
    /// law is built from it before the runtime exists, then the runtime starts with it.
    /// `flash` must be at least two slots ([`SLOT_BYTES`] each).
    pub fn with_flash(scn: &Scenario, flash: RamFlash) -> anyhow::Result<Self> {
        let mut machine = Machine::new(scn)?;
        let range = machine.io.range;
        let mut dev = LawDevice::new(
            profile::follower_config(range.max_code().unsigned_abs()),
            profile::table_limits(),
            Box::new(Table::empty()),
            [
                Box::new(Follower::unconfigured()),
                Box::new(Follower::unconfigured()),
            ],
            FIRMWARE,
        );
        let store = Store::new::<_, AXES, CAPACITY>(&flash, 0, SLOT_BYTES)
            .map_err(|e| anyhow::anyhow!("flash geometry: {e:?}"))?;
        let mut handler = Handler::new(store);
        let mut flash = flash;
        handler.boot(
            &mut BoardDevice::<_, _, _, AXES, CAPACITY, PRESSURES> {
                st: &mut dev,
                glue: &mut machine,
            },
            &mut flash,
        );
        let coeffs = profile::runtime_config()
            .build()
            .map_err(|e| anyhow::anyhow!("the board profile's runtime limits: {e:?}"))?;
        let (rt, refused) = dev.start(coeffs, BootCause::Normal);
        if refused != 0 {
            // As the firmware: reported, the slave stays unreferenced.
            eprintln!("virtual board: persisted offsets not restored (slaves {refused:b})");
        }
        machine.tl = Some(TickLoop::new(rt, 1000, u32::MAX / 1000));
        Ok(Self {
            machine,
            dev,
            handler,
            flash,
            plc: hydra_core::plc::Server::new(0),
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

    /// The runtime (built at the end of boot: always `Some` on a built board).
    pub fn runtime(&self) -> Option<&VRuntime> {
        self.machine.runtime()
    }

    /// Ticks run since boot (one per simulated period, commands' ticks included).
    pub fn ticks(&self) -> u64 {
        self.machine.ticks()
    }

    /// The board's millisecond clock (ticks × period).
    pub fn now_ms(&self) -> u32 {
        (self.machine.ticks() * self.machine.period_ns / 1_000_000) as u32
    }

    /// Modbus function 3.
    pub fn plc_read_holding(
        &self,
        start: u16,
        out: &mut [u16],
    ) -> Result<(), hydra_core::plc::Exception> {
        self.plc.read_holding(start, out)
    }

    /// Modbus function 4: the input image of the last tick.
    pub fn plc_read_input(
        &mut self,
        start: u16,
        out: &mut [u16],
    ) -> Result<(), hydra_core::plc::Exception> {
        let rt = self
            .machine
            .runtime()
            .ok_or(hydra_core::plc::Exception::DeviceFailure)?;
        let st = *rt.status();
        let mut backoff_level = [0u8; AXES];
        let mut speed = 0i32;
        if let Some(law) = rt.law() {
            for (i, l) in backoff_level.iter_mut().enumerate() {
                *l = law.backoff_level(i);
            }
            let v = law.master_estimate().rate_per_s.to_num::<i64>();
            speed = v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
        }
        let live = hydra_core::plc::Live {
            master_speed_counts_per_s: speed,
            // The clock counts ns.
            tick_max_us: u16::try_from(st.timing.max_cycles / 1000).unwrap_or(u16::MAX),
            backoff_level,
        };
        let dev = BoardDevice::<_, _, _, AXES, CAPACITY, PRESSURES> {
            st: &mut self.dev,
            glue: &mut self.machine,
        };
        self.plc
            .read_input(&self.handler, &dev, &st, &live, start, out)
    }

    /// Modbus functions 6 and 16 at the board's clock.
    pub fn plc_write(
        &mut self,
        start: u16,
        values: &[u16],
    ) -> Result<(), hydra_core::plc::Exception> {
        let now = self.now_ms();
        let mut dev = BoardDevice::<_, _, _, AXES, CAPACITY, PRESSURES> {
            st: &mut self.dev,
            glue: &mut self.machine,
        };
        let r = self.plc.write(
            &mut self.handler,
            &mut dev,
            &mut self.flash,
            start,
            values,
            now,
        );
        let _ = self.handler.poll(&mut dev);
        r
    }

    /// Received bytes → responses through `tx`.
    pub fn on_bytes(&mut self, bytes: &[u8], tx: &mut impl FnMut(&[u8])) {
        let mut dev = BoardDevice::<_, _, _, AXES, CAPACITY, PRESSURES> {
            st: &mut self.dev,
            glue: &mut self.machine,
        };
        self.handler.on_bytes(&mut dev, &mut self.flash, bytes, tx);
        // The ticks that answered commands produced samples too.
        for s in std::mem::take(&mut self.machine.host.command_samples) {
            self.handler.on_tick(tx, || telemetry_of(Some(s)));
        }
    }

    /// One control period, with telemetry through `tx` when due; then the link side's
    /// periodic work (a deferred activation, the host-link watchdog), as the firmware's
    /// link task does after each tick.
    pub fn tick(&mut self, tx: &mut impl FnMut(&[u8])) {
        self.machine.tick();
        let mut dev = BoardDevice::<_, _, _, AXES, CAPACITY, PRESSURES> {
            st: &mut self.dev,
            glue: &mut self.machine,
        };
        // A refused deferred activation keeps the running table; Status shows the id.
        let _ = self.handler.poll(&mut dev);
        // The host-link watchdog on the board's own clock (ticks × period).
        let ms = self.machine.ticks() * self.machine.period_ns / 1_000_000;
        let mut dev = BoardDevice::<_, _, _, AXES, CAPACITY, PRESSURES> {
            st: &mut self.dev,
            glue: &mut self.machine,
        };
        self.handler.watch_link(&mut dev, ms as u32);
        let mut dev = BoardDevice::<_, _, _, AXES, CAPACITY, PRESSURES> {
            st: &mut self.dev,
            glue: &mut self.machine,
        };
        self.plc
            .poll(&mut self.handler, &mut dev, &mut self.flash, ms as u32);
        let m = &self.machine;
        self.handler.on_tick(tx, || m.telemetry());
    }
}
