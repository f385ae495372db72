//! The shared-memory holders behind a node's in-place slots
//! ([`harvest_node::in_place`]): a received sample read where iceoryx2 put it, and a loan
//! written where it will be sent from. Each is attached to its slot once, when the ports
//! open; per tick only its contents change.

use std::any::Any;

use harvest_ipc::error::SendError;
use harvest_ipc::payload::Payload;
use harvest_ipc::{Loan, Publisher, Received};
use harvest_node::SampleHolder;

/// The newest sample of a [`harvest_node::LatestInPlace`] slot, held until the next tick.
pub(crate) struct HeldSample<T: Payload> {
    pub(crate) sample: Option<Received<T>>,
}

impl<T: Payload + 'static> SampleHolder<T> for HeldSample<T> {
    fn sample(&self) -> Option<&T> {
        self.sample.as_deref()
    }

    /// A received sample is read-only.
    fn sample_mut(&mut self) -> Option<&mut T> {
        None
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

/// The publisher of a [`harvest_node::Loaned`] slot with its current loan: taken when the
/// node first asks for the sample, kept (as the node left it) until it is sent. A failed
/// loan is kept for the transport to report after the step.
pub(crate) struct LoanHolder<T: Payload> {
    pub(crate) publisher: Publisher<T>,
    pub(crate) loan: Option<Loan<T>>,
    pub(crate) error: Option<SendError>,
}

impl<T: Payload + 'static> SampleHolder<T> for LoanHolder<T> {
    fn sample(&self) -> Option<&T> {
        self.loan.as_deref()
    }

    fn sample_mut(&mut self) -> Option<&mut T> {
        if self.loan.is_none() {
            match self.publisher.loan() {
                Ok(loan) => self.loan = Some(loan),
                Err(error) => {
                    self.error = Some(error);
                    return None;
                }
            }
        }
        self.loan.as_deref_mut()
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

impl<T: Payload> LoanHolder<T> {
    /// After the step: reports a failed loan, or sends the loan if the node marked it.
    pub(crate) fn flush(&mut self, send: bool) -> Result<(), SendError> {
        if let Some(error) = self.error.take() {
            return Err(error);
        }
        if send && let Some(loan) = self.loan.take() {
            self.publisher.send(loan)?;
        }
        Ok(())
    }
}
