//! Frames over any [`embedded_io`] serial port.
//!
//! The firmware passes its UART driver (QEMU's CMSDK UART in the PIL firmware, a HAL's UART
//! on a real board); tests pass byte slices. Reading polls [`ReadReady`] so that a deadline
//! can end the wait: a control tick must not block on a frame that will never come.

use embedded_io::{Read, ReadReady, Write};

use crate::frame::{Frame, FrameError, FrameReader, MAX_WIRE};

/// Why no frame was read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LinkError<E> {
    /// The port failed.
    Io(E),
    /// The deadline passed (or the port reached its end) before a frame was complete.
    Timeout,
    /// Bytes up to a delimiter did not form a valid frame.
    Corrupt(FrameError),
}

/// Writes one frame and flushes the port. A port that accepts no bytes (`write` returning 0)
/// is reported as an error rather than a panic (embedded-io's `write_all` panics there).
pub fn write_frame<W: Write>(port: &mut W, frame: &Frame) -> Result<(), LinkError<W::Error>> {
    let mut wire = [0u8; MAX_WIRE];
    let n = frame.encode(&mut wire);
    let mut rest = wire.get(..n).unwrap_or(&[]);
    while !rest.is_empty() {
        match port.write(rest).map_err(LinkError::Io)? {
            0 => return Err(LinkError::Timeout),
            k => rest = rest.get(k..).unwrap_or(&[]),
        }
    }
    port.flush().map_err(LinkError::Io)
}

/// Reads bytes one at a time into `reader` until a frame ends, or until `expired()` is true
/// while no byte is waiting. A corrupted frame is returned as [`LinkError::Corrupt`] at once
/// (the caller decides whether to keep waiting); the bytes of a later frame stay in the port.
pub fn read_frame<P: Read + ReadReady>(
    port: &mut P,
    reader: &mut FrameReader,
    mut expired: impl FnMut() -> bool,
) -> Result<Frame, LinkError<P::Error>> {
    loop {
        if port.read_ready().map_err(LinkError::Io)? {
            let mut byte = [0u8; 1];
            if port.read(&mut byte).map_err(LinkError::Io)? == 0 {
                return Err(LinkError::Timeout); // end of input
            }
            if let Some(frame) = reader.push(byte[0]) {
                return frame.map_err(LinkError::Corrupt);
            }
        } else if expired() {
            return Err(LinkError::Timeout);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::{Kind, MAX_WIRE};

    /// Checks: two frames written back to back are read back in order from the byte
    /// stream; then the end of input is a timeout.
    #[test]
    fn frames_round_trip_through_a_port() {
        let a = Frame::new(Kind::State, 1, 2).with_values(&[1.0, -2.0]);
        let b = Frame::new(Kind::End, 1, 0);
        let mut buf = [0u8; 2 * MAX_WIRE];
        let mut port: &mut [u8] = &mut buf;
        write_frame(&mut port, &a).unwrap();
        write_frame(&mut port, &b).unwrap();
        let written = 2 * MAX_WIRE - port.len();
        let mut input: &[u8] = &buf[..written];
        let mut reader = FrameReader::new();
        assert_eq!(read_frame(&mut input, &mut reader, || true), Ok(a));
        assert_eq!(read_frame(&mut input, &mut reader, || true), Ok(b));
        assert_eq!(
            read_frame(&mut input, &mut reader, || true),
            Err(LinkError::Timeout)
        );
    }

    /// Checks: a corrupted frame is reported as `Corrupt` and the intact frame after it is
    /// then read normally.
    #[test]
    fn corrupt_frame_then_good_frame() {
        let a = Frame::new(Kind::State, 1, 2).with_values(&[1.0, -2.0]);
        let mut wire = [0u8; MAX_WIRE];
        let n = a.encode(&mut wire);
        let mut bytes = wire[..n].to_vec();
        bytes[3] ^= 0x40;
        bytes.extend_from_slice(&wire[..n]);
        let mut input: &[u8] = &bytes;
        let mut reader = FrameReader::new();
        assert!(matches!(
            read_frame(&mut input, &mut reader, || true),
            Err(LinkError::Corrupt(_))
        ));
        assert_eq!(read_frame(&mut input, &mut reader, || true), Ok(a));
    }

    /// A port with nothing to read, counting how often the deadline is consulted.
    struct Silent;
    impl embedded_io::ErrorType for Silent {
        type Error = core::convert::Infallible;
    }
    impl Read for Silent {
        fn read(&mut self, _: &mut [u8]) -> Result<usize, Self::Error> {
            Ok(0)
        }
    }
    impl ReadReady for Silent {
        fn read_ready(&mut self) -> Result<bool, Self::Error> {
            Ok(false)
        }
    }

    /// Checks: with no byte arriving (a missing frame), the read ends with `Timeout` as soon
    /// as the deadline says so.
    #[test]
    fn missing_frame_times_out() {
        let mut polls = 0;
        let got = read_frame(&mut Silent, &mut FrameReader::new(), || {
            polls += 1;
            polls == 5
        });
        assert_eq!(got, Err(LinkError::Timeout));
        assert_eq!(polls, 5);
    }
}
