//! The handler's side of control ownership (`crate::plc::owner`): which requests need
//! the machine, the serial host's and the PLC's gates, and the PLC's way in — the same
//! dispatch a serial frame gets, so a PLC's write is validated exactly as the host's.

use super::handler::{Device, Handler};
use super::msg::{Nak, NakCode, Request, Response};
use crate::plc::{MachineNow, OwnerError, PlcSettings, Side};
use embedded_storage::nor_flash::NorFlash;

/// Whether `req` moves or configures the machine (needs its owner). Reads, diagnostics,
/// a table upload into the staging bank (nothing runs it until Activate) and **Stop**
/// need none: stopping the machine is never refused to any side.
pub const fn needs_owner(req: &Request<'_>) -> bool {
    matches!(
        req,
        Request::Activate { .. }
            | Request::Start
            | Request::Hold
            | Request::ClearFault
            | Request::SetPosition { .. }
            | Request::Home { .. }
            | Request::Jog { .. }
            | Request::MoveTo { .. }
            | Request::Approach { .. }
            | Request::TestMove { .. }
            | Request::SetParam { .. }
            | Request::Save
    )
}

impl From<OwnerError> for Nak {
    fn from(e: OwnerError) -> Self {
        let (owner, busy) = match e {
            OwnerError::NotOwner { owner } => (owner, 0),
            OwnerError::Busy { owner } => (owner, 1),
        };
        Nak::with(NakCode::NotOwner, owner as u16, busy)
    }
}

impl<const S: usize, const N: usize> Handler<S, N> {
    /// The PLC link's settings in force.
    pub fn plc_settings(&self) -> &PlcSettings<S> {
        &self.plc
    }

    /// Who owns the machine.
    pub fn owner(&self) -> Side {
        self.owner.owner()
    }

    /// The PLC server reports its heartbeat's state: a lost heartbeat lets another side
    /// take the machine from an owning PLC.
    pub fn set_plc_lost(&mut self, lost: bool) {
        self.plc_lost = lost;
    }

    /// What ownership needs to know of the machine now.
    fn machine_now<D: Device<S, N>>(&self, dev: &D) -> MachineNow {
        let owner_timed_out = match self.owner.owner() {
            Side::Host => self.link_lost(),
            Side::Plc => self.plc_lost,
            Side::None => false,
        };
        MachineNow {
            at_rest: dev.all_idle(),
            owner_timed_out,
        }
    }

    /// `side` asks for ownership to go to `wants` (`crate::plc::Ownership::take`).
    pub fn take_owner<D: Device<S, N>>(
        &mut self,
        dev: &D,
        side: Side,
        wants: Side,
    ) -> Result<(), Nak> {
        let now = self.machine_now(dev);
        self.owner.take(side, wants, now)?;
        Ok(())
    }

    /// Whether `side` may send `req`. The serial host takes a machine nobody owns with
    /// its first request that needs it (a board without a PLC works as it always did);
    /// the PLC takes it only by writing `owner`.
    pub(super) fn gate<D: Device<S, N>>(
        &mut self,
        dev: &D,
        side: Side,
        req: &Request<'_>,
    ) -> Result<(), Nak> {
        if !needs_owner(req) {
            return Ok(());
        }
        if side == Side::Host && self.owner.owner() == Side::None {
            self.take_owner(dev, Side::Host, Side::Host)?;
        }
        self.owner.may_write(side)?;
        Ok(())
    }

    /// A request from the PLC (the Modbus server turns register writes into requests):
    /// ownership-gated, then the same dispatch, validation and response as a serial
    /// frame's, without the serial session's sequence rules.
    pub fn plc_request<D: Device<S, N>, F: NorFlash>(
        &mut self,
        dev: &mut D,
        flash: &mut F,
        req: &Request<'_>,
    ) -> Response {
        match self.gate(dev, Side::Plc, req) {
            Ok(()) => self.with_link_kept(|h| h.dispatch(dev, flash, req)),
            Err(nak) => Response::Nak { req: req.ty(), nak },
        }
    }
}
