//! What a backend offers the runner ([`Transport`]), and how a node's input and output structs
//! show their channels to it ([`Inputs`], [`Outputs`]: the node visits its slots, in the same
//! order every time, naming each slot's channel).

use harvest_ipc::catalogue::Channel;
use harvest_ipc::payload::Payload;
use harvest_ipc::payloads::OperatorModeState;

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
}

/// Sees each output slot of a node with its channel.
pub trait OutputVisitor {
    type Error;
    fn output<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut Out<T>,
    ) -> Result<(), Self::Error>;
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
