//! The wire format.
//!
//! A frame's *body* is
//!
//! | bytes | field | |
//! | --- | --- | --- |
//! | 1 | `kind` | [`Kind`] as `u8` |
//! | 1 | `flags` | bit 0: [`FALLBACK`] (an action computed without a valid state) |
//! | 2 | `episode` | `u16` LE |
//! | 2 | `tick` | `u16` LE (Start: ticks per episode; Report: fallback ticks) |
//! | 1 | `count` | number of values, ≤ [`MAX_VALUES`] |
//! | 4·count | `values` | `f32` LE each |
//! | 2 | `crc` | CRC-16/IBM-3740 (poly 0x1021, init 0xFFFF) of all bytes above, LE |
//!
//! On the wire the body is COBS-encoded (Cheshire & Baker 1999), which removes every zero
//! byte, and followed by one `0x00` delimiter. A receiver therefore always knows where a
//! frame ends: after a corrupted, truncated or overlong frame it discards bytes up to the
//! next delimiter and the following frame decodes normally. A frame is accepted only if its
//! COBS encoding, its length (`7 + 4·count + 2` bytes) and its CRC all check out.
//!
//! The largest frame (24 values) is 105 body bytes and 107 wire bytes; a 2-value state frame
//! is 19 wire bytes.

use crc::{CRC_16_IBM_3740, Crc};
use ctrl_adapt::controller::Mode;

/// Most values in one frame (state or action vector).
pub const MAX_VALUES: usize = 24;
/// Header bytes before the values.
const HEADER: usize = 7;
/// The largest body: header, values, CRC.
pub const MAX_BODY: usize = HEADER + 4 * MAX_VALUES + 2;
/// The largest frame on the wire: COBS overhead and the delimiter included.
pub const MAX_WIRE: usize = cobs::max_encoding_length(MAX_BODY) + 1;

/// `flags` bit: the firmware computed this action without a valid state for the tick
/// (corrupted or missing state frame) and used the nominal controller.
pub const FALLBACK: u8 = 1;

/// The frame checksum (table-driven: 512 bytes of flash for the table).
pub const CRC: Crc<u16> = Crc::<u16>::new(&CRC_16_IBM_3740);

/// A state or action vector.
pub type Values = heapless::Vec<f32, MAX_VALUES>;

/// What a frame is; the direction is part of the meaning.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum Kind {
    /// Host → firmware: start `episode` with `tick` control ticks; values: what the host
    /// asks of the episode (the AUV learner: an optional mode, [`crate::mode_code`]).
    Start = 1,
    /// Firmware → host: the episode has started; values: the parameters θ it runs.
    Started = 2,
    /// Host → firmware: the sensor state for (`episode`, `tick`).
    State = 3,
    /// Firmware → host: the actuator command for (`episode`, `tick`).
    Action = 4,
    /// Host → firmware: `episode` is over.
    End = 5,
    /// Firmware → host: the episode's result; `tick`: fallback ticks, values: controller's
    /// report (the AUV learner: its `Report`).
    Report = 6,
    /// Host → firmware: stop.
    Shutdown = 7,
    /// Firmware → host: stopping (answer to Shutdown).
    Bye = 8,
    /// Host → firmware: where does the learner stand? Sent after a (re)boot of a firmware
    /// that keeps its learning state on flash.
    Hello = 9,
    /// Firmware → host: the answer to Hello; `episode`: the next episode the learner expects
    /// (0 on a fresh start, one past the last episode whose end it saved otherwise).
    Resume = 10,
}

impl Kind {
    fn from_u8(v: u8) -> Option<Self> {
        Some(match v {
            1 => Self::Start,
            2 => Self::Started,
            3 => Self::State,
            4 => Self::Action,
            5 => Self::End,
            6 => Self::Report,
            7 => Self::Shutdown,
            8 => Self::Bye,
            9 => Self::Hello,
            10 => Self::Resume,
            _ => return None,
        })
    }
}

/// One decoded frame.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Frame {
    /// What it is.
    pub kind: Kind,
    /// Bit flags ([`FALLBACK`]).
    pub flags: u8,
    /// Episode number.
    pub episode: u16,
    /// Tick within the episode (or a count, see [`Kind`]).
    pub tick: u16,
    /// State, action or report values.
    pub values: Values,
}

/// Why received bytes were not a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// The COBS encoding is invalid.
    Cobs,
    /// More bytes than the largest frame before a delimiter.
    TooLong,
    /// The body length does not match its value count.
    Length,
    /// The checksum does not match.
    Crc,
    /// The checksum matches but the kind is unknown.
    UnknownKind,
}

impl Frame {
    /// A frame with no values.
    pub const fn new(kind: Kind, episode: u16, tick: u16) -> Self {
        Self {
            kind,
            flags: 0,
            episode,
            tick,
            values: Values::new(),
        }
    }

    /// The same frame with `values` (at most [`MAX_VALUES`]; extra values are dropped).
    pub fn with_values(mut self, values: &[f32]) -> Self {
        self.values.clear();
        for &v in values.iter().take(MAX_VALUES) {
            // Cannot fail: at most MAX_VALUES values are pushed.
            let _ = self.values.push(v);
        }
        self
    }

    /// Writes the frame's wire form (COBS body + delimiter) into `out`, returning its length.
    pub fn encode(&self, out: &mut [u8; MAX_WIRE]) -> usize {
        let mut body = [0u8; MAX_BODY];
        let count = self.values.len().min(MAX_VALUES);
        body[0] = self.kind as u8;
        body[1] = self.flags;
        body[2..4].copy_from_slice(&self.episode.to_le_bytes());
        body[4..6].copy_from_slice(&self.tick.to_le_bytes());
        body[6] = count as u8;
        for (chunk, v) in body[HEADER..HEADER + 4 * MAX_VALUES]
            .chunks_exact_mut(4)
            .zip(self.values.iter())
        {
            chunk.copy_from_slice(&v.to_le_bytes());
        }
        let crc_at = HEADER + 4 * count;
        let (covered, rest) = body.split_at_mut(crc_at);
        let crc = CRC.checksum(covered).to_le_bytes();
        if let Some(slot) = rest.first_chunk_mut::<2>() {
            *slot = crc;
        }
        // `get` rather than indexing throughout: the lengths are in range by construction,
        // and the firmware's panic-freedom check must not find a bounds check here.
        let body = body.get(..crc_at + 2).unwrap_or(&[]);
        let (encoded, _) = out.split_at_mut(MAX_WIRE - 1);
        // Cannot fail: MAX_WIRE holds the encoding of the largest body plus the delimiter.
        let n = cobs::try_encode(body, encoded).unwrap_or(0);
        if let Some(delimiter) = out.get_mut(n) {
            *delimiter = 0;
        }
        n + 1
    }

    /// Decodes a body (COBS already removed).
    pub fn decode_body(body: &[u8]) -> Result<Self, FrameError> {
        let (header, _) = body
            .split_first_chunk::<HEADER>()
            .ok_or(FrameError::Length)?;
        let count = usize::from(header[6]);
        if count > MAX_VALUES || body.len() != HEADER + 4 * count + 2 {
            return Err(FrameError::Length);
        }
        let (covered, crc) = body.split_at(HEADER + 4 * count);
        let crc = crc.first_chunk::<2>().ok_or(FrameError::Length)?;
        if CRC.checksum(covered) != u16::from_le_bytes(*crc) {
            return Err(FrameError::Crc);
        }
        let kind = Kind::from_u8(header[0]).ok_or(FrameError::UnknownKind)?;
        let mut values = Values::new();
        for chunk in covered[HEADER..].chunks_exact(4) {
            let bytes = chunk.first_chunk::<4>().ok_or(FrameError::Length)?;
            // Cannot fail: count <= MAX_VALUES.
            let _ = values.push(f32::from_le_bytes(*bytes));
        }
        Ok(Self {
            kind,
            flags: header[1],
            episode: u16::from_le_bytes([header[2], header[3]]),
            tick: u16::from_le_bytes([header[4], header[5]]),
            values,
        })
    }
}

/// Assembles frames from a byte stream, one byte at a time (a UART delivers one byte per
/// read). Holds one wire frame, `MAX_WIRE` bytes.
#[derive(Debug, Clone)]
pub struct FrameReader {
    buf: [u8; MAX_WIRE],
    len: usize,
    overflow: bool,
}

impl Default for FrameReader {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameReader {
    /// An empty reader.
    pub const fn new() -> Self {
        Self {
            buf: [0; MAX_WIRE],
            len: 0,
            overflow: false,
        }
    }

    /// Feeds one byte. At a delimiter, returns the frame that ended (or why it was not a
    /// valid one) and starts afresh; an empty frame (two delimiters in a row) is skipped.
    pub fn push(&mut self, byte: u8) -> Option<Result<Frame, FrameError>> {
        if byte != 0 {
            match self.buf.get_mut(self.len) {
                Some(slot) => {
                    *slot = byte;
                    self.len += 1;
                }
                None => self.overflow = true,
            }
            return None;
        }
        let (len, overflow) = (self.len, self.overflow);
        self.len = 0;
        self.overflow = false;
        if overflow {
            return Some(Err(FrameError::TooLong));
        }
        if len == 0 {
            return None;
        }
        let mut body = [0u8; MAX_WIRE];
        let decoded = self
            .buf
            .get(..len)
            .and_then(|wire| cobs::decode(wire, &mut body).ok())
            .map(|report| report.frame_size());
        Some(match decoded.and_then(|n| body.get(..n)) {
            Some(body) => Frame::decode_body(body),
            None => Err(FrameError::Cobs),
        })
    }
}

/// The wire value of an adapter mode (a Start frame's optional value, a Report's mode):
/// 0 learn, 1 deploy, 2 nominal.
pub const fn mode_code(mode: Mode) -> f32 {
    match mode {
        Mode::Learn => 0.0,
        Mode::Deploy => 1.0,
        Mode::Nominal => 2.0,
    }
}

/// The adapter mode of a wire value, if it is one.
pub fn mode_from_code(code: f32) -> Option<Mode> {
    [Mode::Learn, Mode::Deploy, Mode::Nominal]
        .into_iter()
        .find(|&m| mode_code(m) == code)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Checks: the wire codes of the modes round-trip and nothing else decodes.
    #[test]
    fn mode_codes_round_trip() {
        for m in [Mode::Learn, Mode::Deploy, Mode::Nominal] {
            assert_eq!(mode_from_code(mode_code(m)), Some(m));
        }
        assert_eq!(mode_from_code(f32::NAN), None);
        assert_eq!(mode_from_code(0.5), None);
    }

    fn wire(frame: &Frame) -> Vec<u8> {
        let mut out = [0u8; MAX_WIRE];
        let n = frame.encode(&mut out);
        out[..n].to_vec()
    }

    fn feed(reader: &mut FrameReader, bytes: &[u8]) -> Vec<Result<Frame, FrameError>> {
        bytes.iter().filter_map(|&b| reader.push(b)).collect()
    }

    fn state(tick: u16, x: f32, v: f32) -> Frame {
        Frame::new(Kind::State, 3, tick).with_values(&[x, v])
    }

    /// Checks: frames of every kind, with 0 to 24 values including zero bytes, NaN and
    /// infinities, survive encode → byte-by-byte decode unchanged (NaN compared by bits).
    #[test]
    fn round_trip_all_kinds_and_lengths() {
        let mut reader = FrameReader::new();
        for (k, kind) in (1..=10).filter_map(Kind::from_u8).enumerate() {
            for count in 0..=MAX_VALUES {
                let values: Vec<f32> = (0..count)
                    .map(|i| match i % 5 {
                        0 => 0.0,
                        1 => f32::NAN,
                        2 => f32::NEG_INFINITY,
                        3 => -1.5e-42,
                        _ => i as f32 * 0.25,
                    })
                    .collect();
                let mut frame = Frame::new(kind, k as u16 * 257, count as u16).with_values(&values);
                frame.flags = FALLBACK;
                let bytes = wire(&frame);
                assert_eq!(
                    bytes.iter().filter(|&&b| b == 0).count(),
                    1,
                    "one delimiter"
                );
                assert!(bytes.len() <= MAX_WIRE);
                let got = feed(&mut reader, &bytes);
                assert_eq!(got.len(), 1);
                let got = got[0].clone().unwrap();
                assert_eq!(
                    (got.kind, got.flags, got.episode, got.tick),
                    (kind, FALLBACK, frame.episode, frame.tick)
                );
                let bits = |f: &Frame| f.values.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&got), bits(&frame));
            }
        }
    }

    /// Checks: flipping any single bit of any byte of a frame (the delimiter aside) never
    /// yields a valid frame, and the next, intact frame decodes normally (resync).
    #[test]
    fn every_single_bit_flip_is_detected_and_the_next_frame_survives() {
        let good = wire(&state(7, 0.125, -2.5));
        let next = state(8, 1.0, 2.0);
        for i in 0..good.len() - 1 {
            for bit in 0..8 {
                let mut reader = FrameReader::new();
                let mut bad = good.clone();
                bad[i] ^= 1 << bit;
                let got = feed(&mut reader, &bad);
                assert!(
                    got.iter().all(|r| r.is_err()),
                    "byte {i} bit {bit}: {got:?}"
                );
                let after = feed(&mut reader, &wire(&next));
                assert_eq!(after, vec![Ok(next.clone())], "byte {i} bit {bit}");
            }
        }
    }

    /// Checks: a frame cut short (its tail lost) is rejected and does not swallow the frame
    /// after it; garbage without delimiters longer than a frame is reported as too long.
    #[test]
    fn truncated_frames_and_line_noise_are_rejected() {
        let full = wire(&state(1, 3.0, 4.0));
        let next = state(2, 5.0, 6.0);
        for cut in 1..full.len() - 1 {
            let mut reader = FrameReader::new();
            let mut bytes = full[..cut].to_vec();
            bytes.push(0);
            let got = feed(&mut reader, &bytes);
            assert!(got.iter().all(|r| r.is_err()), "cut {cut}");
            assert_eq!(feed(&mut reader, &wire(&next)), vec![Ok(next.clone())]);
        }
        let mut reader = FrameReader::new();
        let mut noise = vec![0x5a; 3 * MAX_WIRE];
        noise.push(0);
        assert_eq!(feed(&mut reader, &noise), vec![Err(FrameError::TooLong)]);
        assert_eq!(feed(&mut reader, &wire(&next)), vec![Ok(next)]);
    }

    /// Checks: a body with a valid CRC but an inconsistent count or an unknown kind is
    /// rejected with the matching error.
    #[test]
    fn length_and_kind_are_checked() {
        let mut body = vec![Kind::State as u8, 0, 0, 0, 0, 0, 1, 0, 0, 128, 63];
        let crc = CRC.checksum(&body).to_le_bytes();
        body.extend_from_slice(&crc);
        assert!(Frame::decode_body(&body).is_ok());
        let mut long = body.clone();
        long.insert(7, 0);
        assert_eq!(Frame::decode_body(&long), Err(FrameError::Length));
        assert_eq!(Frame::decode_body(&body[..5]), Err(FrameError::Length));
        let mut unknown = body[..11].to_vec();
        unknown[0] = 99;
        let crc = CRC.checksum(&unknown).to_le_bytes();
        unknown.extend_from_slice(&crc);
        assert_eq!(Frame::decode_body(&unknown), Err(FrameError::UnknownKind));
    }
}
