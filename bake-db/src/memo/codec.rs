//! The bytes of a memo entry that checks itself: a body of little-endian words, then a blake3
//! hash of the body. [`Writer`] builds one; [`Reader`] reads one back, checked — a damaged,
//! truncated or over-long entry reads as `None`.

/// A sealed entry's body under construction.
#[derive(Default)]
pub struct Writer(Vec<u8>);

impl Writer {
    /// Appends `v` as a little-endian u32.
    pub fn u32(&mut self, v: u32) -> &mut Self {
        self.0.extend(v.to_le_bytes());
        self
    }

    /// Appends a count (a `usize` that fits a u32: lengths of meshes and bakes).
    pub fn count(&mut self, n: usize) -> &mut Self {
        self.u32(u32::try_from(n).expect("counts in a memo fit 32 bits"))
    }

    /// Appends plain values as their bytes (little-endian on every platform kage builds for).
    pub fn pod<T: bytemuck::Pod>(&mut self, values: &[T]) -> &mut Self {
        self.0.extend_from_slice(bytemuck::cast_slice(values));
        self
    }

    /// The body followed by its blake3 hash.
    pub fn seal(&mut self) -> Vec<u8> {
        let mut out = std::mem::take(&mut self.0);
        let hash = *blake3::hash(&out).as_bytes();
        out.extend(hash);
        out
    }
}

/// A sealed entry's body, read from the front.
pub struct Reader<'a> {
    rest: &'a [u8],
}

impl<'a> Reader<'a> {
    /// The body of `bytes` when its hash holds; `None` otherwise.
    pub fn open(bytes: &'a [u8]) -> Option<Self> {
        let (body, hash) = bytes.split_at_checked(bytes.len().checked_sub(32)?)?;
        (blake3::hash(body).as_bytes() == hash).then_some(Self { rest: body })
    }

    /// The next little-endian u32.
    pub fn u32(&mut self) -> Option<u32> {
        let (word, rest) = self.rest.split_first_chunk::<4>()?;
        self.rest = rest;
        Some(u32::from_le_bytes(*word))
    }

    /// The next count.
    pub fn count(&mut self) -> Option<usize> {
        self.u32().map(|n| n as usize)
    }

    /// The next `n` plain values.
    pub fn pod<T: bytemuck::Pod>(&mut self, n: usize) -> Option<Vec<T>> {
        let (bytes, rest) = self.rest.split_at_checked(n.checked_mul(std::mem::size_of::<T>())?)?;
        self.rest = rest;
        Some(bytemuck::pod_collect_to_vec(bytes))
    }

    /// Every remaining value, when the rest holds a whole number of them.
    pub fn rest<T: bytemuck::Pod>(&mut self) -> Option<Vec<T>> {
        let size = std::mem::size_of::<T>();
        if !self.rest.len().is_multiple_of(size) {
            return None;
        }
        self.pod(self.rest.len() / size)
    }

    /// `value` when the body was read to its end (an over-long body is damaged too).
    pub fn end<T>(self, value: T) -> Option<T> {
        self.rest.is_empty().then_some(value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Written then read: the same values; any flipped bit, truncation or extra byte: `None`.
    #[test]
    fn entries_round_trip_and_damage_reads_as_none() {
        let sealed = Writer::default().count(2).pod(&[1.5f32, -2.0]).u32(7).seal();
        let read = |bytes: &[u8]| {
            let mut r = Reader::open(bytes)?;
            let n = r.count()?;
            let values: Vec<f32> = r.pod(n)?;
            let tail = r.u32()?;
            r.end((values, tail))
        };
        assert_eq!(read(&sealed), Some((vec![1.5, -2.0], 7)));
        for k in 0..sealed.len() {
            let mut damaged = sealed.clone();
            damaged[k] ^= 0x10;
            assert_eq!(read(&damaged), None, "bit flipped in byte {k}");
        }
        assert_eq!(read(&sealed[..sealed.len() - 1]), None);
        let long = Writer::default().count(2).pod(&[1.5f32, -2.0]).u32(7).u32(0).seal();
        assert_eq!(read(&long), None, "an over-long body");
        assert!(Reader::open(&[0; 10]).is_none());
    }
}
