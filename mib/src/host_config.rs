//! The host binary's and the lab network's tuning: ports, input batching, TM write
//! timeout, UDP subscriptions and TCP bounds of the obsw host build and its simulator.
//! Not flight constants: board A's firmware has none of these links.

/// Default UDP/TCP port of robot 1's OBSW; robot N listens on `DEFAULT_PORT + N - 1`
/// when the ground tool starts several OBSWs.
pub const DEFAULT_PORT: u16 = 7301;
/// Host binary: most inputs (TCs, simulator-control lines) handled back to back before
/// a due control period runs.
pub const HOST_INPUT_BATCH: usize = 64;
/// Host binary: most overdue control periods run in a row, inputs left waiting, when the
/// process falls behind the wall clock (one simulated second at the nominal period).
pub const HOST_CATCH_UP_PERIODS: u32 = 100;
/// Longest a TM write may wait for the ground link (a TCP client that stops reading is
/// then dropped; a UDP packet that still cannot go is counted in `IO_TM_DROPPED`). The
/// packet stays in the on-board store either way.
pub const TM_WRITE_TIMEOUT_MS: u32 = 100;
/// Simulator control port of robot N is `SIM_CTL_BASE_PORT + N` (host simulator only).
pub const SIM_CTL_BASE_PORT: u16 = 7400;
/// Bare-packet lab port of robot `n` (UDP and TCP; obsw --udp/--tcp).
pub const fn robot_port(n: u8) -> u16 {
    DEFAULT_PORT - 1 + n as u16
}
/// Robot N's space-link port (one TC frame per datagram, obsw --frame-udp) is
/// `FRAME_BASE_PORT + N`.
pub const FRAME_BASE_PORT: u16 = 7_500;
/// Robot N's TM frames go to `TM_FRAME_BASE_PORT + N` on the ground (obsw
/// --frame-tm-to, ground --tm-listen).
pub const TM_FRAME_BASE_PORT: u16 = 7_600;
/// Space-link TC frame port of robot `n`.
pub const fn frame_port(n: u8) -> u16 {
    FRAME_BASE_PORT + n as u16
}
/// Port robot `n`'s TM frames arrive at on the ground.
pub const fn tm_frame_port(n: u8) -> u16 {
    TM_FRAME_BASE_PORT + n as u16
}
/// OBSW: most UDP grounds receiving TM at once. A ground subscribes with any accepted TC.
pub const MAX_SUBSCRIBERS: usize = 4;
/// OBSW: a UDP subscription ends this long after the ground's last accepted TC.
pub const SUBSCRIPTION_LEASE_MS: u32 = 30_000;
/// OBSW: most TCP clients at once; a further connection is closed at once (counted).
pub const TCP_MAX_CONNECTIONS: usize = 8;
/// OBSW: decoded TCs waiting per TCP connection; when full, the obsw stops reading that
/// connection (the kernel's window then holds the sender back).
pub const TCP_INPUT_QUEUE: usize = 16;
/// OBSW: bytes of TM waiting to be written to one TCP client; a client that falls
/// further behind is disconnected (its TM stays in the on-board store).
pub const TCP_TM_BACKLOG: usize = 256 * 1024;
/// OBSW: longest simulator-control line.
pub const SIM_CTL_MAX_LINE: usize = 256;
