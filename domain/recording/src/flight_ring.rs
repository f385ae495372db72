//! The flight recorder's ring: the recent messages of every recorded channel, at full rate and
//! as the recorder encoded them, in a bounded amount of RAM allocated once.
//!
//! The ring is a fixed set of equal blocks, each a buffer allocated when the ring is made and
//! never grown. Messages are appended back to back into the open block (a small header, then
//! the bytes); a full block is sealed and becomes shareable (`Arc`), so a clip writer on another
//! thread reads sealed blocks while the ring keeps appending into others, without a copy and
//! without a lock. When no block is free, the oldest sealed block is reused, unless a clip
//! writer still holds it: the new message is then left out of the ring and counted (the ring
//! never allocates more, and never waits).

use crate::resident_buffer::resident_buffer;
use std::collections::VecDeque;
use std::sync::Arc;

/// Bytes of a record's header: topic index (u32), sequence (u32), log time (u64), publish time
/// (u64), data length (u32), little-endian.
pub const RECORD_HEADER_BYTES: usize = 4 + 4 + 8 + 8 + 4;

/// One message in the ring. Times are on the stack clock (`CLOCK_MONOTONIC` ns).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RingRecord<'a> {
    pub topic: u32,
    pub sequence: u32,
    pub log_time_ns: u64,
    pub publish_time_ns: u64,
    pub data: &'a [u8],
}

/// A block of records.
#[derive(Debug)]
pub struct Block {
    bytes: Vec<u8>,
    first_log_ns: u64,
    last_log_ns: u64,
    records: u32,
    /// Number of this block's sealing in the ring's life (1, 2, ...; 0 while open).
    seal_number: u64,
}

impl Block {
    fn with_capacity(block_bytes: usize) -> Self {
        Self {
            bytes: resident_buffer(block_bytes),
            first_log_ns: u64::MAX,
            last_log_ns: 0,
            records: 0,
            seal_number: 0,
        }
    }

    fn clear(&mut self) {
        self.bytes.clear();
        self.first_log_ns = u64::MAX;
        self.last_log_ns = 0;
        self.records = 0;
        self.seal_number = 0;
    }

    fn has_room(&self, record_bytes: usize) -> bool {
        self.bytes.capacity() - self.bytes.len() >= record_bytes
    }

    fn push(&mut self, record: &RingRecord<'_>) {
        let length = u32::try_from(record.data.len()).unwrap_or(u32::MAX);
        self.bytes.extend_from_slice(&record.topic.to_le_bytes());
        self.bytes.extend_from_slice(&record.sequence.to_le_bytes());
        self.bytes
            .extend_from_slice(&record.log_time_ns.to_le_bytes());
        self.bytes
            .extend_from_slice(&record.publish_time_ns.to_le_bytes());
        self.bytes.extend_from_slice(&length.to_le_bytes());
        self.bytes.extend_from_slice(record.data);
        self.first_log_ns = self.first_log_ns.min(record.log_time_ns);
        self.last_log_ns = self.last_log_ns.max(record.log_time_ns);
        self.records += 1;
    }

    /// The block's records, in the order appended.
    pub fn records(&self) -> BlockRecords<'_> {
        BlockRecords { rest: &self.bytes }
    }

    pub fn record_count(&self) -> u32 {
        self.records
    }

    /// Earliest log time in the block (`u64::MAX` when empty).
    pub fn first_log_ns(&self) -> u64 {
        self.first_log_ns
    }

    /// Latest log time in the block (0 when empty).
    pub fn last_log_ns(&self) -> u64 {
        self.last_log_ns
    }

    /// When the block was sealed: the ring's count of seals then (0 while open).
    pub fn seal_number(&self) -> u64 {
        self.seal_number
    }

    /// Bytes of records in the block.
    pub fn used_bytes(&self) -> usize {
        self.bytes.len()
    }
}

/// Iterates the records of a block.
pub struct BlockRecords<'a> {
    rest: &'a [u8],
}

impl<'a> Iterator for BlockRecords<'a> {
    type Item = RingRecord<'a>;

    fn next(&mut self) -> Option<Self::Item> {
        let header = self.rest.get(..RECORD_HEADER_BYTES)?;
        let u32_at = |at: usize| {
            u32::from_le_bytes([header[at], header[at + 1], header[at + 2], header[at + 3]])
        };
        let u64_at = |at: usize| {
            let mut bytes = [0u8; 8];
            bytes.copy_from_slice(&header[at..at + 8]);
            u64::from_le_bytes(bytes)
        };
        let length = u32_at(24) as usize;
        let data = self
            .rest
            .get(RECORD_HEADER_BYTES..RECORD_HEADER_BYTES + length)?;
        let record = RingRecord {
            topic: u32_at(0),
            sequence: u32_at(4),
            log_time_ns: u64_at(8),
            publish_time_ns: u64_at(16),
            data,
        };
        self.rest = &self.rest[RECORD_HEADER_BYTES + length..];
        Some(record)
    }
}

/// What the ring did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RingCounts {
    /// Messages appended.
    pub appended: u64,
    /// Messages larger than a block (left out).
    pub dropped_too_large: u64,
    /// Messages left out because every block was held by a clip writer.
    pub dropped_held: u64,
    /// Sealed blocks reused for new messages (their messages left the ring).
    pub blocks_reused: u64,
}

/// The ring.
#[derive(Debug)]
pub struct FlightRing {
    block_bytes: usize,
    blocks: usize,
    free: Vec<Arc<Block>>,
    /// Sealed blocks, oldest first.
    sealed: VecDeque<Arc<Block>>,
    open: Option<Arc<Block>>,
    counts: RingCounts,
    seals: u64,
}

impl FlightRing {
    /// A ring of `capacity_bytes` in blocks of `block_bytes` (at least two blocks). Every block
    /// is allocated here, once, and made resident (every page written), so the ring's memory is
    /// what was configured from the first message on, never more.
    pub fn new(capacity_bytes: usize, block_bytes: usize) -> Self {
        let block_bytes = block_bytes.max(RECORD_HEADER_BYTES + 1);
        let blocks = (capacity_bytes / block_bytes).max(2);
        Self {
            block_bytes,
            blocks,
            free: (0..blocks)
                .map(|_| Arc::new(Block::with_capacity(block_bytes)))
                .collect(),
            sealed: VecDeque::with_capacity(blocks),
            open: None,
            counts: RingCounts::default(),
            seals: 0,
        }
    }

    /// Bytes the ring holds at most (its blocks' buffers): the RAM it takes once full.
    pub fn capacity_bytes(&self) -> usize {
        self.blocks * self.block_bytes
    }

    pub fn block_bytes(&self) -> usize {
        self.block_bytes
    }

    pub fn counts(&self) -> RingCounts {
        self.counts
    }

    /// Earliest log time still in the ring.
    pub fn oldest_log_ns(&self) -> Option<u64> {
        self.sealed
            .iter()
            .chain(self.open.iter())
            .map(|block| block.first_log_ns)
            .min()
    }

    /// Appends a message; `false` when it was left out (counted).
    pub fn append(&mut self, record: &RingRecord<'_>) -> bool {
        let record_bytes = RECORD_HEADER_BYTES + record.data.len();
        if record_bytes > self.block_bytes {
            self.counts.dropped_too_large += 1;
            return false;
        }
        let fits = self
            .open
            .as_ref()
            .is_some_and(|block| block.has_room(record_bytes));
        if !fits {
            self.seal();
            match self.take_block() {
                Some(block) => self.open = Some(block),
                None => {
                    self.counts.dropped_held += 1;
                    return false;
                }
            }
        }
        // The open block is never shared (only sealed blocks are handed out).
        match self.open.as_mut().and_then(Arc::get_mut) {
            Some(block) => {
                block.push(record);
                self.counts.appended += 1;
                true
            }
            None => {
                self.counts.dropped_held += 1;
                false
            }
        }
    }

    /// Seals the open block (when it holds records), so [`Self::sealed_since`] hands it out.
    pub fn seal(&mut self) {
        if let Some(mut block) = self.open.take() {
            if block.records > 0 {
                self.seals += 1;
                if let Some(open) = Arc::get_mut(&mut block) {
                    open.seal_number = self.seals;
                }
                self.sealed.push_back(block);
            } else {
                self.free.push(block);
            }
        }
    }

    /// Sealed blocks holding messages logged at or after `from_ns`, oldest first (shared, not
    /// copied: the ring does not reuse them while they are held).
    pub fn sealed_since(&self, from_ns: u64) -> Vec<Arc<Block>> {
        self.sealed
            .iter()
            .filter(|block| block.last_log_ns >= from_ns)
            .cloned()
            .collect()
    }

    /// Sealed blocks with a seal number above `seal_number`, oldest first.
    pub fn sealed_after(&self, seal_number: u64) -> Vec<Arc<Block>> {
        self.sealed
            .iter()
            .filter(|block| block.seal_number > seal_number)
            .cloned()
            .collect()
    }

    /// Blocks sealed so far in the ring's life.
    pub fn seal_count(&self) -> u64 {
        self.seals
    }

    fn take_block(&mut self) -> Option<Arc<Block>> {
        if let Some(block) = self.free.pop() {
            return Some(block);
        }
        let oldest = self.sealed.front_mut()?;
        let block = Arc::get_mut(oldest)?;
        block.clear();
        self.counts.blocks_reused += 1;
        self.sealed.pop_front()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(topic: u32, sequence: u32, log_time_ns: u64, data: &[u8]) -> RingRecord<'_> {
        RingRecord {
            topic,
            sequence,
            log_time_ns,
            publish_time_ns: log_time_ns - 1,
            data,
        }
    }

    fn all_records(blocks: &[Arc<Block>]) -> Vec<(u32, u64, Vec<u8>)> {
        blocks
            .iter()
            .flat_map(|block| {
                block
                    .records()
                    .map(|r| (r.sequence, r.log_time_ns, r.data.to_vec()))
                    .collect::<Vec<_>>()
            })
            .collect()
    }

    #[test]
    fn keeps_the_newest_messages_within_its_capacity() {
        // 4 blocks of 100 bytes: 2 records of 20 data bytes (48 each) per block.
        let mut ring = FlightRing::new(400, 100);
        assert_eq!(ring.capacity_bytes(), 400);
        for n in 0..20u32 {
            assert!(ring.append(&record(1, n, 1_000 + u64::from(n), &[n as u8; 20])));
        }
        ring.seal();
        let kept = all_records(&ring.sealed_since(0));
        // The last 4 blocks' worth: 8 messages, in order, bytes intact.
        let sequences: Vec<u32> = kept.iter().map(|r| r.0).collect();
        assert_eq!(sequences, (12..20).collect::<Vec<_>>());
        assert!(kept.iter().all(|r| r.2 == vec![r.0 as u8; 20]));
        assert_eq!(ring.oldest_log_ns(), Some(1_012));
        assert_eq!(ring.counts().appended, 20);
        assert!(ring.counts().blocks_reused >= 6);
        // A window from a time on.
        let since: Vec<u32> = all_records(&ring.sealed_since(1_017))
            .iter()
            .map(|r| r.0)
            .collect();
        assert_eq!(since, vec![16, 17, 18, 19]);
        assert_eq!(ring.seal_count(), 10);
        let newest: Vec<u32> = all_records(&ring.sealed_after(9))
            .iter()
            .map(|r| r.0)
            .collect();
        assert_eq!(newest, vec![18, 19]);
    }

    #[test]
    fn held_blocks_are_not_reused_and_nothing_is_allocated_past_the_capacity() {
        let mut ring = FlightRing::new(300, 100);
        for n in 0..6u32 {
            assert!(ring.append(&record(1, n, u64::from(n) + 10, &[0; 20])));
        }
        ring.seal();
        let held = ring.sealed_since(0);
        assert_eq!(held.len(), 3);
        // Every block is held: new messages are left out and counted.
        assert!(!ring.append(&record(1, 6, 20, &[0; 20])));
        assert_eq!(ring.counts().dropped_held, 1);
        drop(held);
        assert!(ring.append(&record(1, 7, 21, &[0; 20])));
        // Too large for a block.
        assert!(!ring.append(&record(1, 8, 22, &[0; 100])));
        assert_eq!(ring.counts().dropped_too_large, 1);
        assert_eq!(ring.capacity_bytes(), 300);
    }
}
