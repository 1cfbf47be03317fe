//! Test doubles for `embedded-hal` 1.0 peripherals.

use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use embedded_hal::i2c::{ErrorKind, ErrorType, I2c, Operation};
use embedded_hal::pwm::{ErrorType as PwmErrorType, SetDutyCycle};

/// An I2C bus with one device: a 256-byte register file with auto-increment, or, for
/// command-byte devices (ADS7828), a fixed reply per command byte.
pub struct MockI2c {
    pub addr: u8,
    pub regs: [u8; 256],
    /// (command byte, 2-byte reply) for command devices.
    pub replies: heapless::Vec<(u8, [u8; 2]), 16>,
    pub writes: heapless::Vec<heapless::Vec<u8, 8>, 16>,
    pub fail: bool,
    pointer: u8,
}

impl MockI2c {
    pub fn new(addr: u8) -> Self {
        Self {
            addr,
            regs: [0; 256],
            replies: heapless::Vec::new(),
            writes: heapless::Vec::new(),
            fail: false,
            pointer: 0,
        }
    }
}

impl ErrorType for MockI2c {
    type Error = ErrorKind;
}

impl I2c for MockI2c {
    fn transaction(&mut self, address: u8, ops: &mut [Operation<'_>]) -> Result<(), ErrorKind> {
        if self.fail || address != self.addr {
            return Err(ErrorKind::NoAcknowledge(
                embedded_hal::i2c::NoAcknowledgeSource::Address,
            ));
        }
        for op in ops {
            match op {
                Operation::Write(data) => {
                    let mut v = heapless::Vec::new();
                    let _ = v.extend_from_slice(&data[..data.len().min(8)]);
                    let _ = self.writes.push(v);
                    if let Some((&first, rest)) = data.split_first() {
                        self.pointer = first;
                        // Register writes: the bytes after the pointer are stored.
                        for (i, b) in rest.iter().enumerate() {
                            self.regs[first.wrapping_add(i as u8) as usize] = *b;
                        }
                    }
                }
                Operation::Read(buf) => {
                    if let Some((_, reply)) = self.replies.iter().find(|(c, _)| *c == self.pointer) {
                        for (i, b) in buf.iter_mut().enumerate() {
                            *b = reply.get(i).copied().unwrap_or(0);
                        }
                    } else {
                        for (i, b) in buf.iter_mut().enumerate() {
                            *b = self.regs[self.pointer.wrapping_add(i as u8) as usize];
                        }
                    }
                }
            }
        }
        Ok(())
    }
}

#[derive(Default)]
pub struct MockPin {
    pub high: bool,
    pub changes: u32,
}

impl PinErrorType for MockPin {
    type Error = core::convert::Infallible;
}

impl OutputPin for MockPin {
    fn set_low(&mut self) -> Result<(), Self::Error> {
        self.high = false;
        self.changes += 1;
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Self::Error> {
        self.high = true;
        self.changes += 1;
        Ok(())
    }
}

impl embedded_hal::digital::InputPin for MockPin {
    fn is_high(&mut self) -> Result<bool, Self::Error> {
        Ok(self.high)
    }
    fn is_low(&mut self) -> Result<bool, Self::Error> {
        Ok(!self.high)
    }
}

pub struct MockPwm {
    pub max: u16,
    pub duty: u16,
}

impl PwmErrorType for MockPwm {
    type Error = core::convert::Infallible;
}

impl SetDutyCycle for MockPwm {
    fn max_duty_cycle(&self) -> u16 {
        self.max
    }
    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Self::Error> {
        self.duty = duty;
        Ok(())
    }
}

/// The arm-switch line with a switchable internal pull (module discovery's probe). A
/// connected arm module drives the line through its own pull-up and its switch to
/// ground: high when released, low when pushed, whatever the internal pull. With no
/// module the line follows the internal pull.
pub struct MockSwitchLine {
    pub connected: bool,
    pub pushed: bool,
    /// The internal pull selected last (true = up).
    pub pull_up: bool,
    /// Reads made.
    pub reads: u32,
}

impl MockSwitchLine {
    /// A connected arm module.
    pub fn arm(pushed: bool) -> Self {
        Self {
            connected: true,
            pushed,
            pull_up: true,
            reads: 0,
        }
    }
}

impl fw_core::modules::PullProbe for MockSwitchLine {
    fn level_with_pull(&mut self, pull_up: bool) -> Result<bool, fw_core::periph::HwError> {
        self.pull_up = pull_up;
        self.reads += 1;
        Ok(if self.connected { !self.pushed } else { pull_up })
    }
}

/// Datagrams a mock radio holds in each direction.
pub const RADIO_QUEUE: usize = 32;
type Datagram = ([u8; mmic_team::wire::MAX_LEN], usize);

/// A mock inter-robot radio (`fw_core::team::TeamTransport`): what the robot sends waits
/// in an outbox until the test's medium ([`MockRadio::take_sent`]) carries it to the other
/// radios' inboxes ([`MockRadio::deliver`]), where `receive` finds it.
pub struct MockRadio {
    outbox: heapless::Deque<(mmic_team::Dest, Datagram), RADIO_QUEUE>,
    inbox: heapless::Deque<Datagram, RADIO_QUEUE>,
}

impl Default for MockRadio {
    fn default() -> Self {
        Self::new()
    }
}

impl MockRadio {
    pub const fn new() -> Self {
        Self {
            outbox: heapless::Deque::new(),
            inbox: heapless::Deque::new(),
        }
    }

    /// The medium takes the next sent datagram.
    pub fn take_sent(&mut self) -> Option<(mmic_team::Dest, Datagram)> {
        self.outbox.pop_front()
    }

    /// The medium delivers a datagram to this radio.
    pub fn deliver(&mut self, bytes: &[u8]) -> Result<(), fw_core::team::TransportError> {
        let mut d = [0u8; mmic_team::wire::MAX_LEN];
        let n = bytes.len();
        if n > d.len() {
            return Err(fw_core::team::TransportError::TooLong { len: n, max: d.len() });
        }
        d[..n].copy_from_slice(bytes);
        self.inbox
            .push_back((d, n))
            .map_err(|_| fw_core::team::TransportError::Full)
    }
}

impl fw_core::team::TeamTransport for MockRadio {
    const MAX_PACKET: usize = mmic_team::wire::MAX_LEN;

    fn send(&mut self, to: mmic_team::Dest, packet: &[u8]) -> Result<(), fw_core::team::TransportError> {
        let mut d = [0u8; mmic_team::wire::MAX_LEN];
        let n = packet.len();
        if n > Self::MAX_PACKET {
            return Err(fw_core::team::TransportError::TooLong {
                len: n,
                max: Self::MAX_PACKET,
            });
        }
        d[..n].copy_from_slice(packet);
        self.outbox
            .push_back((to, (d, n)))
            .map_err(|_| fw_core::team::TransportError::Full)
    }

    fn receive(&mut self, buf: &mut [u8]) -> Result<Option<usize>, fw_core::team::TransportError> {
        let Some((d, n)) = self.inbox.pop_front() else {
            return Ok(None);
        };
        if n > buf.len() {
            return Err(fw_core::team::TransportError::TooLong { len: n, max: buf.len() });
        }
        buf[..n].copy_from_slice(&d[..n]);
        Ok(Some(n))
    }
}
