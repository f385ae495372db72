//! What a backend offers the runner ([`Transport`]), and how a node's input and output structs
//! show their channels to it ([`Inputs`], [`Outputs`]: the node visits its slots, in the same
//! order every time, naming each slot's channel).

use harvest_ipc::catalogue::Channel;
use harvest_ipc::payload::Payload;
use harvest_ipc::payloads::OperatorModeState;

use crate::in_place::{LatestInPlace, Loaned};
use crate::ports::{Drain, Latest, Out};

/// Sees each input slot of a node with its channel.
pub trait InputVisitor {
    type Error;
    /// A channel read as its newest sample.
    fn latest<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut Latest<T>,
    ) -> Result<(), Self::Error>;
    /// A channel read as every sample since the previous tick.
    fn drain<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut Drain<T>,
    ) -> Result<(), Self::Error>;
    /// A channel of large messages read as its newest sample, in place (see
    /// [`crate::in_place`]). Default, for a backend without shared memory: the slot stays
    /// empty.
    fn latest_in_place<T: Payload + 'static>(
        &mut self,
        _channel: Channel<T>,
        _slot: &mut LatestInPlace<T>,
    ) -> Result<(), Self::Error> {
        Ok(())
    }
}

/// Sees each output slot of a node with its channel.
pub trait OutputVisitor {
    type Error;
    fn output<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut Out<T>,
    ) -> Result<(), Self::Error>;
    /// A channel of large messages written in place into a loaned sample (see
    /// [`crate::in_place`]). Default, for a backend without shared memory: nothing to lend,
    /// nothing sent.
    fn loaned<T: Payload + 'static>(
        &mut self,
        _channel: Channel<T>,
        slot: &mut Loaned<T>,
    ) -> Result<(), Self::Error> {
        let _ = slot.take_send::<()>();
        Ok(())
    }
}

/// A node's input struct: visits every slot, always in the same order.
pub trait Inputs {
    fn visit<V: InputVisitor>(&mut self, visitor: &mut V) -> Result<(), V::Error>;
}

/// A node's output struct: visits every slot, always in the same order.
pub trait Outputs {
    fn visit<V: OutputVisitor>(&mut self, visitor: &mut V) -> Result<(), V::Error>;
}

/// A node with no inputs or no outputs.
impl Inputs for () {
    fn visit<V: InputVisitor>(&mut self, _: &mut V) -> Result<(), V::Error> {
        Ok(())
    }
}

impl Outputs for () {
    fn visit<V: OutputVisitor>(&mut self, _: &mut V) -> Result<(), V::Error> {
        Ok(())
    }
}

/// A backend's channels as the runner uses them. The emergency stop and the operator's mode
/// are the runner's own inputs (every node obeys them), read before the node's.
pub trait Transport {
    type Error: std::error::Error + Send + Sync + 'static;
    /// The newest `safety/emergency_stop` sample since the previous call, if any: engaged?
    fn emergency_stop(&mut self) -> Result<Option<bool>, Self::Error>;
    /// The newest `operator/mode` sample since the previous call, if any.
    fn operator_mode(&mut self) -> Result<Option<OperatorModeState>, Self::Error>;
    /// Fills the node's input slots.
    fn read_inputs<I: Inputs>(&mut self, inputs: &mut I) -> Result<(), Self::Error>;
    /// Sends and empties the node's output slots.
    fn publish<O: Outputs>(&mut self, outputs: &mut O) -> Result<(), Self::Error>;
}
