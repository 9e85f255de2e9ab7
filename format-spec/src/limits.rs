//! Limits applied before allocating anything whose size comes from a file.
//!
//! Every parser in regolith takes a [`Limits`]; lengths read from input go through
//! [`Limits::check_len`] so a corrupt or hostile file cannot make us allocate gigabytes.

use crate::FormatError;

/// Upper bounds on sizes read from untrusted input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Maximum number of points in one point cloud.
    pub max_points: u64,
    /// Maximum side length of an image, in pixels.
    pub max_image_side: u32,
    /// Maximum size of one object or record, in bytes.
    pub max_object_bytes: u64,
    /// Maximum number of bytes allocated for one buffer.
    pub max_alloc_bytes: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_points: 200_000_000,
            max_image_side: 32_768,
            max_object_bytes: 8 << 30,
            max_alloc_bytes: 8 << 30,
        }
    }
}

impl Limits {
    /// Checks a length read from input against `limit`, returning it as `usize`.
    pub fn check_len(what: &'static str, found: u64, limit: u64) -> Result<usize, FormatError> {
        if found > limit {
            return Err(FormatError::LimitExceeded { what, found, limit });
        }
        usize::try_from(found).map_err(|_| FormatError::LimitExceeded {
            what,
            found,
            limit: usize::MAX as u64,
        })
    }

    /// Allocates an empty vector with room for `n` elements after checking the byte budget.
    pub fn vec_with_capacity<T>(&self, what: &'static str, n: u64) -> Result<Vec<T>, FormatError> {
        let bytes = n.saturating_mul(std::mem::size_of::<T>() as u64);
        Self::check_len(what, bytes, self.max_alloc_bytes)?;
        #[allow(clippy::disallowed_methods)]
        Ok(Vec::with_capacity(n as usize))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_len_rejects_above_limit() {
        assert!(Limits::check_len("points", 11, 10).is_err());
        assert_eq!(Limits::check_len("points", 10, 10).unwrap(), 10);
        let l = Limits {
            max_alloc_bytes: 64,
            ..Limits::default()
        };
        assert!(l.vec_with_capacity::<f64>("buf", 9).is_err());
        assert_eq!(l.vec_with_capacity::<f64>("buf", 8).unwrap().capacity(), 8);
    }
}
