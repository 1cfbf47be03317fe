//! Transfer frames over a byte stream (a serial line, USB CDC-ACM, a pty, a Unix socket):
//! each TC or TM frame is one COBS frame between two 0x00 delimiters,
//! `0x00, COBS(frame), 0x00` — the framing board A's ground link uses (docs/firmware.md).
//!
//! The codec is the `mmic-stream` crate, re-exported here: [`encode`], [`encoded_len`] and
//! the incremental receiver [`Deframer`] with its [`StreamCounters`] and [`StreamError`]
//! (the one deframer of the host, the ground, the tests and the firmware).
//!
//! With the `std` feature, [`port`] opens a serial device (raw mode) or a Unix socket as
//! a non-blocking byte stream with a bounded send queue: the host obsw's
//! `--frame-serial` and the ground's `--serial` both use it.

pub use mmic_stream::{encode, encoded_len, Deframer, StreamCounters, StreamError};

/// The host end of a stream link (`std`): a serial device in raw mode, a pty, or a Unix
/// socket, non-blocking, with a bounded send queue so a slow line never blocks the caller.
#[cfg(all(feature = "std", unix))]
pub mod port {
    use std::collections::VecDeque;
    use std::fs::{File, OpenOptions};
    use std::io::{self, Read, Write};
    use std::os::fd::{AsFd, AsRawFd, BorrowedFd, RawFd};
    use std::os::unix::fs::{FileTypeExt, OpenOptionsExt};
    use std::os::unix::net::UnixStream;
    use std::path::Path;
    use std::time::Duration;

    use nix::poll::{PollFd, PollFlags, PollTimeout};
    use nix::sys::termios;

    /// Default bound of the send queue: about 60 TM frames of 1031 bytes on the wire.
    pub const SEND_QUEUE: usize = 64 * 1024;

    enum Io {
        Tty(File),
        Unix(UnixStream),
    }

    /// An open stream port (see the module documentation).
    pub struct Port {
        io: Io,
        out: VecDeque<u8>,
        limit: usize,
        /// Whole frames refused because the send queue had no room for them.
        pub send_dropped: u64,
        /// What the port is (for messages): `tty PATH` or `unix socket PATH`.
        pub describe: String,
    }

    /// Opens `path`: a Unix socket is connected to (for QEMU's `-serial unix:PATH,server`
    /// and tests); anything else is opened as a terminal device, put in raw mode (8 bits,
    /// no echo, no line editing, no flow control; the speed is left as it is — USB
    /// CDC-ACM ignores it, a UART needs `stty -F PATH SPEED` first) and its stale input
    /// discarded.
    pub fn open(path: &Path) -> io::Result<Port> {
        let meta = std::fs::metadata(path)?;
        let (io, describe) = if meta.file_type().is_socket() {
            let s = UnixStream::connect(path)?;
            s.set_nonblocking(true)?;
            (Io::Unix(s), format!("unix socket {}", path.display()))
        } else {
            let f = OpenOptions::new()
                .read(true)
                .write(true)
                .custom_flags(libc::O_NOCTTY | libc::O_NONBLOCK)
                .open(path)?;
            raw_mode(&f)?;
            (Io::Tty(f), format!("tty {}", path.display()))
        };
        Ok(Port {
            io,
            out: VecDeque::new(),
            limit: SEND_QUEUE,
            send_dropped: 0,
            describe,
        })
    }

    /// Raw mode on a terminal (a no-op error for files that are not terminals is
    /// reported), then its input queue flushed.
    fn raw_mode(f: &File) -> io::Result<()> {
        let mut t = termios::tcgetattr(f.as_fd()).map_err(io::Error::from)?;
        termios::cfmakeraw(&mut t);
        t.control_flags |= termios::ControlFlags::CLOCAL | termios::ControlFlags::CREAD;
        t.control_flags &= !termios::ControlFlags::CRTSCTS;
        t.control_chars[termios::SpecialCharacterIndices::VMIN as usize] = 0;
        t.control_chars[termios::SpecialCharacterIndices::VTIME as usize] = 0;
        termios::tcsetattr(f.as_fd(), termios::SetArg::TCSANOW, &t).map_err(io::Error::from)?;
        termios::tcflush(f.as_fd(), termios::FlushArg::TCIFLUSH).map_err(io::Error::from)?;
        Ok(())
    }

    /// Puts a terminal (e.g. a test's pty side) in raw mode.
    pub fn set_raw(f: &impl AsFd) -> io::Result<()> {
        let mut t = termios::tcgetattr(f.as_fd()).map_err(io::Error::from)?;
        termios::cfmakeraw(&mut t);
        termios::tcsetattr(f.as_fd(), termios::SetArg::TCSANOW, &t).map_err(io::Error::from)
    }

    impl Port {
        /// A connected Unix stream (a test's socket pair) as a port.
        pub fn from_unix(s: UnixStream) -> io::Result<Port> {
            s.set_nonblocking(true)?;
            Ok(Port {
                io: Io::Unix(s),
                out: VecDeque::new(),
                limit: SEND_QUEUE,
                send_dropped: 0,
                describe: "unix stream".into(),
            })
        }

        /// Sets the bound of the send queue (bytes).
        pub fn set_send_limit(&mut self, bytes: usize) {
            self.limit = bytes;
        }

        fn fd(&self) -> BorrowedFd<'_> {
            match &self.io {
                Io::Tty(f) => f.as_fd(),
                Io::Unix(s) => s.as_fd(),
            }
        }

        /// The descriptor, for an event loop (readable when bytes wait).
        pub fn raw_fd(&self) -> RawFd {
            self.fd().as_raw_fd()
        }

        /// Reads what is waiting (never blocks): `Ok(0)` when nothing is (or, on a tty,
        /// nobody is at the other end yet).
        pub fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            let r = match &mut self.io {
                Io::Tty(f) => f.read(buf),
                Io::Unix(s) => match s.read(buf) {
                    Ok(0) => Err(io::Error::new(io::ErrorKind::UnexpectedEof, "unix socket closed")),
                    r => r,
                },
            };
            match r {
                Ok(n) => Ok(n),
                Err(e) if e.kind() == io::ErrorKind::WouldBlock || e.kind() == io::ErrorKind::Interrupted => Ok(0),
                // A pty whose other side is not open (yet): nothing to read.
                Err(e) if e.raw_os_error() == Some(libc::EIO) => Ok(0),
                Err(e) => Err(e),
            }
        }

        /// Queues a whole encoded frame and writes as much as the line takes. False when
        /// the queue had no room: the frame was dropped whole (counted in
        /// `send_dropped`), never cut.
        pub fn send(&mut self, bytes: &[u8]) -> io::Result<bool> {
            self.flush()?;
            if self.out.len() + bytes.len() > self.limit {
                self.send_dropped += 1;
                return Ok(false);
            }
            self.out.extend(bytes);
            self.flush()?;
            Ok(true)
        }

        /// Writes queued bytes until the line would block.
        pub fn flush(&mut self) -> io::Result<()> {
            while !self.out.is_empty() {
                let (a, _) = self.out.as_slices();
                let r = match &mut self.io {
                    Io::Tty(f) => f.write(a),
                    Io::Unix(s) => s.write(a),
                };
                match r {
                    Ok(0) => return Ok(()),
                    Ok(n) => {
                        self.out.drain(..n);
                    }
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                    Err(e) if e.kind() == io::ErrorKind::WouldBlock => return Ok(()),
                    Err(e) if e.raw_os_error() == Some(libc::EIO) => return Ok(()),
                    Err(e) => return Err(e),
                }
            }
            Ok(())
        }

        /// Bytes queued and not yet written.
        pub fn queued(&self) -> usize {
            self.out.len()
        }

        /// Waits until bytes can be read (or, with bytes queued, written) or `timeout`
        /// passes.
        pub fn wait(&self, timeout: Duration) -> io::Result<()> {
            let mut flags = PollFlags::POLLIN;
            if !self.out.is_empty() {
                flags |= PollFlags::POLLOUT;
            }
            let ms = u16::try_from(timeout.as_millis()).unwrap_or(u16::MAX);
            let mut fds = [PollFd::new(self.fd(), flags)];
            match nix::poll::poll(&mut fds, PollTimeout::from(ms)) {
                Ok(_) => {
                    // A tty with nobody at the other end reports POLLHUP at once: do not spin.
                    let hup = fds[0].revents().is_some_and(|r| r.contains(PollFlags::POLLHUP));
                    if hup {
                        std::thread::sleep(timeout.min(Duration::from_millis(5)));
                    }
                    Ok(())
                }
                Err(nix::errno::Errno::EINTR) => Ok(()),
                Err(e) => Err(e.into()),
            }
        }
    }
}
