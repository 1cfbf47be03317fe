//! One control period of each board, generic over the peripheral traits: the exact code
//! the board images run every 10 ms, and what the on-target tests run against mock
//! peripherals.

use crate::config;
use crate::files::FileService;
use crate::link::{self, ByteQueue, Counters, TcChannel};
use crate::periph::{
    AnalogInput, AngleSensor, Enable, GravitySensor, HwError, PairSelect, ServoOutput, SideOutputs, Switch,
};
use crate::sampling::{sample_a, sample_b, SensorErrors};
use mmic_domain::board_b::{BoardB, BoardBOut};
use mmic_domain::{ActuatorsA, SensorsA, SensorsB};
use obsw_core::obsw::{IoCounters, Obsw};
use obsw_core::tm::{TmSink, TmStore};

/// Board A's ground link as the control period sees it: takes the uplinked TCs, sends
/// TM, and closes each period. The images use the frame link
/// ([`crate::spacelink::FrameLink`]); tests of the control period may use their own.
pub trait GroundLink {
    /// Executes the TCs waiting in `tcs` (their replies go to `tm`); a packet the file
    /// service takes goes to it instead of the OBSW (an authenticated link only).
    fn receive<S: TmStore, F: FileService, const N: usize>(
        &mut self,
        now: u64,
        obsw: &mut Obsw<S>,
        files: &mut F,
        tcs: &TcChannel,
        tm: &ByteQueue<N>,
        tm_stats: &Counters,
    );
    /// Sends one TM packet.
    fn send_tm<const N: usize>(&mut self, packet: &[u8], tm: &ByteQueue<N>, tm_stats: &Counters);
    /// Bytes of replayed TM the link takes this period without dropping any, one largest
    /// packet kept for the period's realtime TM (`TmSink::replay_room`).
    fn replay_room<const N: usize>(&self, tm: &ByteQueue<N>) -> usize;
    /// End of the period (flushes, link counters and events).
    fn end_period<S: TmStore, const N: usize>(
        &mut self,
        now: u64,
        obsw: &mut Obsw<S>,
        tm: &ByteQueue<N>,
        tm_stats: &Counters,
    );
}

impl<St: mmic_link::sdls::IvStore + mmic_link::endpoint::StoreStats> GroundLink for crate::spacelink::FrameLink<St> {
    fn receive<S: TmStore, F: FileService, const N: usize>(
        &mut self,
        now: u64,
        obsw: &mut Obsw<S>,
        files: &mut F,
        tcs: &TcChannel,
        tm: &ByteQueue<N>,
        tm_stats: &Counters,
    ) {
        crate::spacelink::FrameLink::receive(self, now, obsw, files, tcs, tm, tm_stats)
    }
    fn send_tm<const N: usize>(&mut self, packet: &[u8], tm: &ByteQueue<N>, tm_stats: &Counters) {
        crate::spacelink::FrameLink::send_tm(self, packet, tm, tm_stats)
    }
    fn replay_room<const N: usize>(&self, tm: &ByteQueue<N>) -> usize {
        crate::spacelink::FrameLink::replay_room(self, tm)
    }
    fn end_period<S: TmStore, const N: usize>(
        &mut self,
        now: u64,
        obsw: &mut Obsw<S>,
        tm: &ByteQueue<N>,
        tm_stats: &Counters,
    ) {
        crate::spacelink::FrameLink::end_period(self, now, obsw, tm, tm_stats)
    }
}

/// The OBSW's TM sink over a [`GroundLink`].
pub struct GroundSink<'a, L, const N: usize> {
    pub link: &'a mut L,
    pub queue: &'a ByteQueue<N>,
    pub counters: &'a Counters,
}

impl<L: GroundLink, const N: usize> TmSink for GroundSink<'_, L, N> {
    fn send_tm(&mut self, packet: &[u8]) {
        self.link.send_tm(packet, self.queue, self.counters);
    }
    fn replay_room(&self) -> usize {
        self.link.replay_room(self.queue)
    }
}

/// Board A's peripherals.
pub struct PeripheralsA<Adc, Imu, Enc, Sw, A, G, T, R, M, H, E> {
    pub adc: Adc,
    pub imu: Imu,
    pub hip_encoder: Enc,
    pub arm_switch: Sw,
    pub side: SideOutputs<A, G, T, R, M>,
    pub hip: H,
    pub regulator: E,
}

/// Board B's peripherals.
pub struct PeripheralsB<Adc, Imu, Sw, A, G, T, R, M> {
    pub adc: Adc,
    pub imu: Imu,
    pub arm_switch: Sw,
    pub side: SideOutputs<A, G, T, R, M>,
}

impl<Adc, Imu, Enc, Sw, A, G, T, R, M, H, E> PeripheralsA<Adc, Imu, Enc, Sw, A, G, T, R, M, H, E>
where
    Adc: AnalogInput,
    Imu: GravitySensor,
    Enc: AngleSensor,
    Sw: Switch,
    A: ServoOutput,
    G: ServoOutput,
    T: ServoOutput,
    R: ServoOutput,
    M: PairSelect,
    H: ServoOutput,
    E: Enable,
{
    /// Everything unpowered, regulator off (boot).
    pub fn release_all(&mut self) {
        self.side.release_all();
        let _ = self.hip.release();
        let _ = self.regulator.set_enabled(false);
    }

    /// Drives every output; all are attempted, the first error is returned.
    pub fn apply(&mut self, act: &ActuatorsA) -> Result<(), HwError> {
        let reg = self.regulator.set_enabled(act.regulator_on);
        let side = self.side.apply(&act.side, act.mux);
        let hip = match act.hip_speed {
            Some(speed) => self.hip.set_pulse_us(crate::periph::servo::hip_pulse(speed)),
            None => self.hip.release(),
        };
        reg.and(side).and(hip)
    }
}

/// The queues board A's control task talks through.
///
/// Each queue comes with the counters its producer keeps; the control task reports them
/// in housekeeping structure PLATFORM_IO.
pub struct LinksA<'a, const TM: usize, const RX: usize, const TX: usize> {
    /// Uplinked TCs, and the uplink's counters (frames dropped: queue full, framing).
    pub tcs: &'a TcChannel,
    pub tc_stats: &'a Counters,
    /// Downlink frames, and their counters (TM not sent live: queue full).
    pub tm: &'a ByteQueue<TM>,
    pub tm_stats: &'a Counters,
    /// Bytes from board B, and the receiver's counters (bytes dropped: queue full).
    pub ab_rx: &'a ByteQueue<RX>,
    pub ab_rx_stats: &'a Counters,
    /// Bytes for board B, and their counters (bytes dropped: queue full).
    pub ab_tx: &'a ByteQueue<TX>,
    pub ab_tx_stats: &'a Counters,
}

impl<const TM: usize, const RX: usize, const TX: usize> LinksA<'_, TM, RX, TX> {
    /// The link part of the platform I/O counters (sensor and output errors are the
    /// control loop's own).
    fn io_counters(&self) -> IoCounters {
        let (up, down) = (self.tc_stats.get(), self.tm_stats.get());
        let (rx, tx) = (self.ab_rx_stats.get(), self.ab_tx_stats.get());
        IoCounters {
            tc_dropped: up.overflow.wrapping_add(up.frame_errors),
            tm_dropped: down.overflow.wrapping_add(down.frame_errors),
            sensor_errors: 0,
            output_errors: 0,
            ab_bytes_dropped: rx.overflow.wrapping_add(tx.overflow),
            stack_high_water: 0,
        }
    }
}

/// State of board A's control loop between periods.
pub struct CycleA {
    pub sensors: SensorsA,
    pub errors: SensorErrors,
    /// Outputs that failed to apply since boot.
    pub output_errors: u32,
    rx: [u8; config::AB_RX_BYTES],
}

impl Default for CycleA {
    fn default() -> Self {
        Self::new()
    }
}

impl CycleA {
    pub const fn new() -> Self {
        Self {
            sensors: SensorsA {
                v_bat: 0,
                i_bat: 0,
                v_reg: 0,
                i_loc: 0,
                i_grip: 0,
                i_bo: 0,
                grav: [0; 3],
                hip_cdeg: 0,
                arm_switch: false,
            },
            errors: SensorErrors {
                adc: 0,
                imu: 0,
                encoder: 0,
                switch: 0,
                last: None,
            },
            output_errors: 0,
            rx: [0; config::AB_RX_BYTES],
        }
    }

    /// Platform I/O counters (housekeeping PLATFORM_IO): TCs dropped by the uplink, live
    /// TM not sent, failed sensor reads and output writes, A–B bytes dropped.
    pub fn io_counters<const TM: usize, const RX: usize, const TX: usize>(
        &self,
        links: &LinksA<'_, TM, RX, TX>,
    ) -> IoCounters {
        IoCounters {
            sensor_errors: self.errors.total(),
            output_errors: self.output_errors,
            ..links.io_counters()
        }
    }

    /// One period: queued TCs, sensors, `Obsw::tick`, the file service's PDUs, outputs,
    /// bytes for board B. Returns the actuator commands applied.
    #[allow(clippy::too_many_arguments)]
    pub fn run<S, L, F, Adc, Imu, Enc, Sw, A, G, T, R, M, H, E, const TM: usize, const RX: usize, const TX: usize>(
        &mut self,
        now: u64,
        obsw: &mut Obsw<S>,
        ground: &mut L,
        files: &mut F,
        io: &mut PeripheralsA<Adc, Imu, Enc, Sw, A, G, T, R, M, H, E>,
        links: &LinksA<'_, TM, RX, TX>,
    ) -> ActuatorsA
    where
        S: TmStore,
        L: GroundLink,
        F: FileService,
        Adc: AnalogInput,
        Imu: GravitySensor,
        Enc: AngleSensor,
        Sw: Switch,
        A: ServoOutput,
        G: ServoOutput,
        T: ServoOutput,
        R: ServoOutput,
        M: PairSelect,
        H: ServoOutput,
        E: Enable,
    {
        // The platform's I/O counters as of the start of this period, for housekeeping
        // PLATFORM_IO (a one-shot TC[3,27] below included; what fails during this
        // period is reported from the next one).
        // The stack's high-water mark is the image's to set (fw_core::stack), kept here.
        obsw.io = IoCounters {
            stack_high_water: obsw.io.stack_high_water,
            ..self.io_counters(links)
        };
        // Telecommands first, so that a TC and the tick that starts it share `now`.
        ground.receive(now, obsw, files, links.tcs, links.tm, links.tm_stats);
        sample_a(
            &mut io.adc,
            &mut io.imu,
            &mut io.hip_encoder,
            &mut io.arm_switch,
            &mut self.sensors,
            &mut self.errors,
        );
        let n = link::drain(links.ab_rx, &mut self.rx);
        let mut sink = GroundSink {
            link: &mut *ground,
            queue: links.tm,
            counters: links.tm_stats,
        };
        let out = obsw.tick(now, &self.sensors, &self.rx[..n], &mut sink);
        // After the OBSW's TM (a PUS 15 replay included): the file PDUs take what room
        // the downlink has left.
        files.poll(now, &mut sink);
        // A failing output keeps its last state; the OBSW sees the effect in currents and
        // positions and its FDIR acts on them.
        if io.apply(&out.actuators).is_err() {
            self.output_errors = self.output_errors.wrapping_add(1);
        }
        link::push_bytes(links.ab_tx, &out.link_tx, links.ab_tx_stats);
        let actuators = out.actuators;
        // HK FILES and the transfer events, as the host obsw reports them (the tick's
        // output is done with: the report borrows the OBSW).
        files.report(now, obsw, &mut sink);
        ground.end_period(now, obsw, links.tm, links.tm_stats);
        actuators
    }
}

/// The queues board B's control task talks through.
pub struct LinksB<'a, const RX: usize, const TX: usize> {
    pub ab_rx: &'a ByteQueue<RX>,
    pub ab_tx: &'a ByteQueue<TX>,
    pub ab_tx_stats: &'a Counters,
}

/// State of board B's control loop between periods.
pub struct CycleB {
    pub board: BoardB,
    pub out: BoardBOut,
    pub sensors: SensorsB,
    pub errors: SensorErrors,
    pub output_errors: u32,
    rx: [u8; config::AB_RX_BYTES],
}

impl Default for CycleB {
    fn default() -> Self {
        Self::new()
    }
}

impl CycleB {
    pub fn new() -> Self {
        Self {
            board: BoardB::new(),
            out: BoardBOut::default(),
            sensors: SensorsB::default(),
            errors: SensorErrors::default(),
            output_errors: 0,
            rx: [0; config::AB_RX_BYTES],
        }
    }

    /// One period: sensors, `BoardB::tick` (commands, acks, heartbeat), outputs.
    pub fn run<Adc, Imu, Sw, A, G, T, R, M, const RX: usize, const TX: usize>(
        &mut self,
        now: u64,
        io: &mut PeripheralsB<Adc, Imu, Sw, A, G, T, R, M>,
        links: &LinksB<'_, RX, TX>,
    ) where
        Adc: AnalogInput,
        Imu: GravitySensor,
        Sw: Switch,
        A: ServoOutput,
        G: ServoOutput,
        T: ServoOutput,
        R: ServoOutput,
        M: PairSelect,
    {
        sample_b(
            &mut io.adc,
            &mut io.imu,
            &mut io.arm_switch,
            &mut self.sensors,
            &mut self.errors,
        );
        let n = link::drain(links.ab_rx, &mut self.rx);
        self.board.tick(now, &self.sensors, &self.rx[..n], &mut self.out);
        if io.side.apply(&self.out.side, self.out.mux).is_err() {
            self.output_errors = self.output_errors.wrapping_add(1);
        }
        link::push_bytes(links.ab_tx, &self.out.tx, links.ab_tx_stats);
    }
}
