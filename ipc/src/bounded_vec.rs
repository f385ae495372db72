//! A fixed-capacity vector for zero-copy payloads (no heap, every bit pattern of `len` checked).

use iceoryx2::prelude::ZeroCopySend;
use serde::de::{SeqAccess, Visitor};
use serde::ser::SerializeSeq;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Up to `N` items of `T`; only the first `len` are meaningful. Serializes as a sequence of the
/// meaningful items only (so `_reserved` is not part of the encoding).
///
/// In memory: `len` (u32), 4 reserved bytes, then the items, which thus start at offset 8 for
/// any item of alignment up to 8, with no padding.
#[repr(C)]
#[derive(Clone, Copy, ZeroCopySend, crate::AnyBitPattern)]
pub struct BoundedVec<T: Copy + Default + ZeroCopySend, const N: usize> {
    len: u32,
    _reserved: u32,
    items: [T; N],
}

impl<T: Copy + Default + ZeroCopySend, const N: usize> BoundedVec<T, N> {
    /// The largest number of items (`N`).
    pub const CAPACITY: usize = N;

    /// An empty vector (all slots default).
    pub fn new() -> Self {
        Self {
            len: 0,
            _reserved: 0,
            items: [T::default(); N],
        }
    }

    /// The meaningful items; a corrupt `len` larger than `N` is clamped.
    pub fn as_slice(&self) -> &[T] {
        &self.items[..(self.len as usize).min(N)]
    }

    /// The number of meaningful items.
    pub fn len(&self) -> usize {
        self.as_slice().len()
    }

    /// Whether there are no items.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Forgets every item (the slots keep their bytes).
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// Appends; returns the item back when full.
    pub fn push(&mut self, item: T) -> Result<(), T> {
        let index = self.len();
        if index >= N {
            return Err(item);
        }
        self.items[index] = item;
        self.len = index as u32 + 1;
        Ok(())
    }

    /// The meaningful items, in order.
    pub fn iter(&self) -> std::slice::Iter<'_, T> {
        self.as_slice().iter()
    }
}

impl<T: Copy + Default + ZeroCopySend, const N: usize> Default for BoundedVec<T, N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Copy + Default + ZeroCopySend + std::fmt::Debug, const N: usize> std::fmt::Debug
    for BoundedVec<T, N>
{
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.as_slice()).finish()
    }
}

impl<T: Copy + Default + ZeroCopySend + PartialEq, const N: usize> PartialEq for BoundedVec<T, N> {
    fn eq(&self, other: &Self) -> bool {
        self.as_slice() == other.as_slice()
    }
}

impl<T: Copy + Default + ZeroCopySend + Serialize, const N: usize> Serialize for BoundedVec<T, N> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut seq = serializer.serialize_seq(Some(self.len()))?;
        for item in self.as_slice() {
            seq.serialize_element(item)?;
        }
        seq.end()
    }
}

/// Written as a sequence: a u64 count, then the meaningful items (at most `N`).
impl<T, const N: usize> crate::schema::Describe for BoundedVec<T, N>
where
    T: Copy + Default + ZeroCopySend + crate::schema::Describe,
{
    fn shape() -> crate::schema::Shape {
        crate::schema::Shape::Sequence {
            item: Box::new(T::shape()),
            max_len: N,
        }
    }
}

impl<'de, T, const N: usize> Deserialize<'de> for BoundedVec<T, N>
where
    T: Copy + Default + ZeroCopySend + Deserialize<'de>,
{
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct SeqVisitor<T, const N: usize>(std::marker::PhantomData<T>);
        impl<'de, T, const N: usize> Visitor<'de> for SeqVisitor<T, N>
        where
            T: Copy + Default + ZeroCopySend + Deserialize<'de>,
        {
            type Value = BoundedVec<T, N>;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                write!(f, "a sequence of at most {N} items")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
                let mut out = BoundedVec::new();
                while let Some(item) = seq.next_element()? {
                    out.push(item)
                        .map_err(|_| serde::de::Error::custom(format!("more than {N} items")))?;
                }
                Ok(out)
            }
        }
        deserializer.deserialize_seq(SeqVisitor::<T, N>(std::marker::PhantomData))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn push_until_full_and_round_trip() {
        let mut values = BoundedVec::<u32, 3>::new();
        for v in 0..3 {
            values.push(v).expect("room");
        }
        assert_eq!(values.push(9), Err(9));
        let mut bytes = Vec::new();
        crate::codec::encode_into(&values, &mut bytes).expect("encode");
        assert_eq!(bytes.len(), 8 + 3 * 4);
        let back: BoundedVec<u32, 3> = crate::codec::decode_exact(&bytes).expect("decode");
        assert_eq!(back, values);
    }
}
