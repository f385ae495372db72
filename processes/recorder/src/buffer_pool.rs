//! The receiving thread's recycled encode buffers: small ones for the many small messages, and
//! a fixed set of frame buffers, each as big as the largest recorded message and resident from
//! the start ([`resident_buffer`]). Encoding a camera frame then never allocates, and the
//! recorder's memory does not move with how many frames happen to be in flight.
//!
//! Only a buffer that can hold any message goes back among the frame buffers. Buffers of other
//! sizes come back too (the writer returns every buffer it wrote: mapped images, video access
//! units, depth images), and letting one of them take a frame buffer's place would make the next
//! frame grow it (a fresh frame-sized allocation) while a resident frame buffer is freed: the
//! recorder's private memory would then step up and down by a frame as the mix changes.

use harvest_recording::resident_buffer::resident_buffer;

/// Buffers at least this big count as large: they are kept only if they can hold a frame.
pub const LARGE_BUFFER_BYTES: usize = 64 * 1024;
/// Small buffers kept for reuse.
const MAX_FREE_SMALL: usize = 256;
/// Frame buffers made at start and kept. A buffer needed beyond these (while all are in
/// flight) is allocated then and freed when it comes back to a full pool.
pub const FRAME_BUFFERS: usize = 8;

/// The pool (module docs).
#[derive(Debug)]
pub struct BufferPool {
    free_small: Vec<Vec<u8>>,
    free_frames: Vec<Vec<u8>>,
    /// Capacity of a frame buffer: the largest encoded message, at least [`LARGE_BUFFER_BYTES`].
    frame_bytes: usize,
    /// Large buffers allocated because no frame buffer was free.
    allocated_beyond_pool: u64,
}

impl BufferPool {
    /// A pool whose frame buffers hold `largest_message_bytes` each (none when every message
    /// is small).
    pub fn new(largest_message_bytes: usize) -> Self {
        let free_frames = if largest_message_bytes >= LARGE_BUFFER_BYTES {
            (0..FRAME_BUFFERS)
                .map(|_| resident_buffer(largest_message_bytes))
                .collect()
        } else {
            Vec::new()
        };
        Self {
            free_small: Vec::new(),
            free_frames,
            frame_bytes: largest_message_bytes.max(LARGE_BUFFER_BYTES),
            allocated_beyond_pool: 0,
        }
    }

    /// An empty buffer for a message of about `size_hint` bytes.
    pub fn take(&mut self, size_hint: usize) -> Vec<u8> {
        if size_hint < LARGE_BUFFER_BYTES {
            return self
                .free_small
                .pop()
                .unwrap_or_else(|| Vec::with_capacity(size_hint));
        }
        self.free_frames.pop().unwrap_or_else(|| {
            self.allocated_beyond_pool += 1;
            tracing::debug!(
                total = self.allocated_beyond_pool,
                "frame buffer pool empty: a buffer allocated"
            );
            Vec::with_capacity(size_hint.max(self.frame_bytes))
        })
    }

    /// Takes a buffer back: kept if there is room for it among its kind, else freed. A large
    /// buffer that cannot hold a frame is always freed.
    pub fn give_back(&mut self, mut buffer: Vec<u8>) {
        buffer.clear();
        let capacity = buffer.capacity();
        if capacity >= self.frame_bytes {
            if self.free_frames.len() < FRAME_BUFFERS {
                self.free_frames.push(buffer);
            }
        } else if capacity < LARGE_BUFFER_BYTES && self.free_small.len() < MAX_FREE_SMALL {
            self.free_small.push(buffer);
        }
    }

    /// Large buffers allocated so far because no frame buffer was free.
    pub fn allocated_beyond_pool(&self) -> u64 {
        self.allocated_beyond_pool
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FRAME: usize = 6 << 20;

    #[test]
    fn frames_are_encoded_into_the_buffers_made_at_start() {
        let mut pool = BufferPool::new(FRAME);
        let taken: Vec<Vec<u8>> = (0..FRAME_BUFFERS).map(|_| pool.take(FRAME)).collect();
        assert!(taken.iter().all(|b| b.capacity() >= FRAME && b.is_empty()));
        assert_eq!(pool.allocated_beyond_pool(), 0);
        let beyond = pool.take(FRAME);
        assert_eq!(pool.allocated_beyond_pool(), 1);
        for buffer in taken.into_iter().chain([beyond]) {
            pool.give_back(buffer);
        }
        assert_eq!(pool.free_frames.len(), FRAME_BUFFERS);
    }

    #[test]
    fn a_large_buffer_smaller_than_a_frame_never_takes_a_frame_buffers_place() {
        let mut pool = BufferPool::new(FRAME);
        let frame = pool.take(FRAME);
        // A mapped image or a depth image the writer hands back.
        pool.give_back(Vec::with_capacity(512 * 1024));
        assert_eq!(pool.free_frames.len(), FRAME_BUFFERS - 1);
        pool.give_back(frame);
        for _ in 0..FRAME_BUFFERS {
            assert!(pool.take(FRAME).capacity() >= FRAME);
        }
        assert_eq!(pool.allocated_beyond_pool(), 0);
    }

    #[test]
    fn small_messages_share_small_buffers_and_a_pool_of_small_messages_has_no_frames() {
        let mut pool = BufferPool::new(4096);
        assert!(pool.free_frames.is_empty());
        let small = pool.take(100);
        pool.give_back(small);
        assert_eq!(pool.free_small.len(), 1);
        assert!(pool.take(LARGE_BUFFER_BYTES).capacity() >= LARGE_BUFFER_BYTES);
        assert_eq!(pool.allocated_beyond_pool(), 1);
    }
}
