//! The PLC link's settings (`plc/…` and `axis/<n>/in_position_um` of the settings
//! tree), kept by the protocol handler beside the host-link watchdog: they belong to the
//! links, not to the control law, so the device never sees them.
//!
//! | path | unit | default | range |
//! |---|---|---|---|
//! | `plc/enable` | bool | 0 (off) | 0, 1 |
//! | `plc/heartbeat_ms` | ms | 1 000 | 0 (off), 50 … 60 000 |
//! | `plc/unit_id` | — | 1 | 1 … 247 |
//! | `plc/allow/<n>/high`, `…/low` | a·256+b, c·256+d | 0 (empty) | 0 … 65 535 |
//! | `axis/<n>/in_position_um` | µm | 100 | 0 … 10⁶ |

use crate::protocol::msg::{Nak, NakCode};
use crate::protocol::ParamId;

/// Allowed Modbus TCP clients (`plc/allow/<n>`).
pub const ALLOW_ENTRIES: usize = 2;

/// Default heartbeat time, ms.
const HEARTBEAT_MS: u32 = 1000;
/// Default unit id.
const UNIT_ID: u8 = 1;
/// Default in-position window, µm.
const IN_POSITION_UM: f32 = 100.0;

/// The PLC link's settings on a board of `S` slaves.
///
/// Each field is stored as its bits XOR its default's, so the defaults are all-zero
/// bytes: the handler that holds these stays a zero-initialised static (`.bss`, no
/// flash image of its 21 KiB). Read them through the accessors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlcSettings<const S: usize> {
    enable: bool,
    heartbeat_x: u32,
    unit_id_x: u8,
    /// Allowed TCP clients, IPv4 as a big-endian `u32` (0: an empty entry).
    allow: [u32; ALLOW_ENTRIES],
    in_position_x: [u32; S],
}

impl<const S: usize> PlcSettings<S> {
    /// The settings at power-up, before a saved set applies (all-zero bytes).
    pub const DEFAULT: Self = Self {
        enable: false,
        heartbeat_x: 0,
        unit_id_x: 0,
        allow: [0; ALLOW_ENTRIES],
        in_position_x: [0; S],
    };

    /// The PLC link answers requests.
    pub const fn enable(&self) -> bool {
        self.enable
    }

    /// Heartbeat time, ms (0: off).
    pub const fn heartbeat_ms(&self) -> u32 {
        self.heartbeat_x ^ HEARTBEAT_MS
    }

    /// The Modbus unit id (RTU address).
    pub const fn unit_id(&self) -> u8 {
        self.unit_id_x ^ UNIT_ID
    }

    /// The allowed TCP clients (0: an empty entry).
    pub const fn allow(&self) -> [u32; ALLOW_ENTRIES] {
        self.allow
    }

    /// The in-position window of slave `i`, µm (0 for a slave the board does not have).
    pub fn in_position_um(&self, i: usize) -> f32 {
        self.in_position_x
            .get(i)
            .map_or(0.0, |x| f32::from_bits(x ^ IN_POSITION_UM.to_bits()))
    }

    /// The allow entry and half a parameter sets: (entry, high half).
    fn allow_slot(p: ParamId) -> Option<(usize, bool)> {
        match p {
            ParamId::PlcAllow0High => Some((0, true)),
            ParamId::PlcAllow0Low => Some((0, false)),
            ParamId::PlcAllow1High => Some((1, true)),
            ParamId::PlcAllow1Low => Some((1, false)),
            _ => None,
        }
    }

    /// Sets `p` (one of the PLC link's) of slave `axis` to `value`, checked against its
    /// range ([`ParamId::check`]) and its own rule (a heartbeat of 0 or ≥ 50 ms).
    /// Errors: `ParamRange`, `UnknownParam` (not a PLC setting, or no such slave); on an
    /// error nothing changes.
    pub fn set(&mut self, axis: u8, p: ParamId, value: f32) -> Result<(), Nak> {
        let v = p.check(axis, value)?;
        let range = Nak::with(NakCode::ParamRange, u16::from(axis), p as u8);
        // Checked an integer within the (u16-sized) range by `check`: the casts are exact.
        match p {
            ParamId::PlcEnable => self.enable = v != 0.0,
            ParamId::PlcHeartbeatMs if v != 0.0 && v < 50.0 => return Err(range),
            ParamId::PlcHeartbeatMs => self.heartbeat_x = (v as u32) ^ HEARTBEAT_MS,
            ParamId::PlcUnitId => self.unit_id_x = (v as u8) ^ UNIT_ID,
            ParamId::InPositionUm => {
                let w = self
                    .in_position_x
                    .get_mut(usize::from(axis))
                    .ok_or(Nak::with(NakCode::UnknownParam, u16::from(axis), p as u8))?;
                *w = v.to_bits() ^ IN_POSITION_UM.to_bits();
            }
            _ => {
                let (entry, high) = Self::allow_slot(p).ok_or(Nak::with(
                    NakCode::UnknownParam,
                    u16::from(axis),
                    p as u8,
                ))?;
                let half = v as u32;
                if let Some(a) = self.allow.get_mut(entry) {
                    *a = if high {
                        (*a & 0xFFFF) | (half << 16)
                    } else {
                        (*a & 0xFFFF_0000) | half
                    };
                }
            }
        }
        Ok(())
    }

    /// The value of `p` of slave `axis` in its unit; `UnknownParam` as [`Self::set`].
    pub fn get(&self, axis: u8, p: ParamId) -> Result<f32, Nak> {
        let unknown = Nak::with(NakCode::UnknownParam, u16::from(axis), p as u8);
        Ok(match p {
            ParamId::PlcEnable => f32::from(u8::from(self.enable)),
            ParamId::PlcHeartbeatMs => self.heartbeat_ms() as f32,
            ParamId::PlcUnitId => f32::from(self.unit_id()),
            ParamId::InPositionUm if usize::from(axis) < S => {
                self.in_position_um(usize::from(axis))
            }
            ParamId::InPositionUm => return Err(unknown),
            _ => {
                let (entry, high) = Self::allow_slot(p).ok_or(unknown)?;
                let a = self.allow.get(entry).copied().unwrap_or(0);
                let half = if high { a >> 16 } else { a & 0xFFFF };
                half as f32
            }
        })
    }

    /// Whether a TCP client at IPv4 `addr` may connect: every entry empty, or one equal
    /// to it.
    pub fn allows(&self, addr: [u8; 4]) -> bool {
        let a = u32::from_be_bytes(addr);
        self.allow.iter().all(|&e| e == 0) || self.allow.contains(&a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_set_read_back_and_refuse_out_of_range_whole() {
        let mut s = PlcSettings::<2>::DEFAULT;
        assert!(!s.enable() && s.heartbeat_ms() == 1000 && s.unit_id() == 1);
        assert_eq!(s.in_position_um(1), 100.0);
        s.set(0, ParamId::PlcEnable, 1.0).unwrap();
        assert_eq!(s.get(0, ParamId::PlcEnable), Ok(1.0));
        let before = s;
        for (p, v) in [
            (ParamId::PlcEnable, 2.0),
            (ParamId::PlcHeartbeatMs, 20.0),
            (ParamId::PlcHeartbeatMs, 10.5),
            (ParamId::PlcUnitId, 0.0),
            (ParamId::PlcUnitId, 248.0),
            (ParamId::PlcAllow0High, 65_536.0),
            (ParamId::InPositionUm, -1.0),
            (ParamId::InPositionUm, f32::NAN),
        ] {
            let e = s.set(0, p, v).unwrap_err();
            assert_eq!(e.code, NakCode::ParamRange, "{p:?} {v}");
            assert_eq!(s, before, "{p:?} {v}: a refusal changes nothing");
        }
        assert!(s.set(2, ParamId::InPositionUm, 5.0).is_err(), "no slave 2");
        assert!(
            s.set(0, ParamId::KpLsbPerUm, 1.0).is_err(),
            "not a PLC setting"
        );
        s.set(0, ParamId::PlcHeartbeatMs, 0.0).unwrap();
        s.set(1, ParamId::InPositionUm, 25.0).unwrap();
        assert_eq!((s.in_position_um(0), s.in_position_um(1)), (100.0, 25.0));
    }

    #[test]
    fn the_defaults_are_all_zero_bytes_so_the_handler_stays_in_bss() {
        let d = PlcSettings::<2>::DEFAULT;
        assert!(!d.enable && d.heartbeat_x == 0 && d.unit_id_x == 0);
        assert!(d.allow == [0; ALLOW_ENTRIES] && d.in_position_x == [0; 2]);
    }

    #[test]
    fn the_allow_list_is_two_halves_per_address() {
        let mut s = PlcSettings::<1>::DEFAULT;
        assert!(s.allows([10, 0, 0, 7]), "an empty list allows every client");
        s.set(0, ParamId::PlcAllow0High, (127 * 256) as f32)
            .unwrap();
        s.set(0, ParamId::PlcAllow0Low, 1.0).unwrap();
        assert_eq!(s.allow()[0], 0x7F00_0001);
        assert!(s.allows([127, 0, 0, 1]));
        assert!(!s.allows([127, 0, 0, 2]));
        assert_eq!(s.get(0, ParamId::PlcAllow0High), Ok(32_512.0));
        assert_eq!(s.get(0, ParamId::PlcAllow1Low), Ok(0.0));
    }
}
