//! Buffers made resident when they are made: every page of the capacity written once, so that
//! the kernel backs the whole buffer now. A process that holds such buffers for its whole life
//! (the flight ring's blocks, the recorder's frame buffers) has its memory at its final size
//! from the start, not creeping up as the buffers happen to be filled further, and filling them
//! never takes a page fault.

/// Bytes of a memory page (the smallest the kernel backs; huge pages are multiples of it).
const PAGE_BYTES: usize = 4096;

/// An empty buffer of `capacity_bytes`, resident.
pub fn resident_buffer(capacity_bytes: usize) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(capacity_bytes);
    let spare = bytes.spare_capacity_mut();
    for page in spare.chunks_mut(PAGE_BYTES) {
        page[0].write(0);
    }
    std::hint::black_box(&*spare);
    bytes
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_buffer_is_empty_with_the_capacity_asked() {
        let buffer = resident_buffer(3 * PAGE_BYTES + 5);
        assert!(buffer.is_empty());
        assert!(buffer.capacity() >= 3 * PAGE_BYTES + 5);
        assert!(resident_buffer(0).is_empty());
    }
}
