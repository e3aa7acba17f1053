//! The per-level tables of an [`Analysis`](super::Analysis) (`et`, `qe`, the similarity
//! sets): an owned vector, or a view of an analysis file mapped into memory
//! ([`Analysis::load_mapped`](super::Analysis::load_mapped)).
//!
//! Why views: the tables are most of an analysis file (55 MB for a 400 px exemplar), and
//! reading them into fresh memory costs a page fault per 4 KiB page. On a CPU device
//! (lavapipe) those faults slowed the device creation that runs beside the load; a
//! mapped file's pages come from the page cache as they are read.
//!
//! A `Table` reads like a slice (`Deref<Target = [T]>`). Writing to a mapped table
//! ([`Table::to_mut`], `DerefMut`) first copies it into an owned vector; the file is never
//! written.

use std::fmt;
use std::ops::{Deref, DerefMut};
use std::sync::Arc;

/// A table of plain values: owned, or borrowed from a mapped analysis file.
pub struct Table<T> {
    repr: Repr<T>,
}

enum Repr<T> {
    Owned(Vec<T>),
    /// `len` values at byte `offset` of `map`, aligned for `T` (checked on creation).
    Mapped {
        map: Arc<memmap2::Mmap>,
        offset: usize,
        len: usize,
    },
}

impl<T: bytemuck::Pod> Table<T> {
    /// An empty (owned) table.
    pub fn new() -> Self {
        Self {
            repr: Repr::Owned(Vec::new()),
        }
    }

    /// `len` values at byte `offset` of `map`, or `None` when they do not fit in it or
    /// are not aligned for `T` there.
    pub(crate) fn mapped(map: Arc<memmap2::Mmap>, offset: usize, len: usize) -> Option<Self> {
        let bytes = len.checked_mul(std::mem::size_of::<T>())?;
        let end = offset.checked_add(bytes)?;
        let aligned = (map.as_ptr() as usize + offset).is_multiple_of(std::mem::align_of::<T>());
        (end <= map.len() && aligned).then_some(Self {
            repr: Repr::Mapped { map, offset, len },
        })
    }

    /// Whether the values are read from a mapped file (rather than owned).
    pub fn is_mapped(&self) -> bool {
        matches!(self.repr, Repr::Mapped { .. })
    }

    /// The values as an owned vector to change; a mapped table is copied first.
    pub fn to_mut(&mut self) -> &mut Vec<T> {
        if self.is_mapped() {
            self.repr = Repr::Owned(self.to_vec());
        }
        match &mut self.repr {
            Repr::Owned(v) => v,
            Repr::Mapped { .. } => unreachable!("converted to an owned vector above"),
        }
    }

    /// The values as an owned vector (a copy for a mapped table).
    pub fn into_vec(self) -> Vec<T> {
        match self.repr {
            Repr::Owned(v) => v,
            Repr::Mapped { .. } => self.to_vec(),
        }
    }
}

impl<T: bytemuck::Pod> Deref for Table<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        match &self.repr {
            Repr::Owned(v) => v,
            Repr::Mapped { map, offset, len } => {
                bytemuck::cast_slice(&map[*offset..*offset + *len * std::mem::size_of::<T>()])
            }
        }
    }
}

impl<T: bytemuck::Pod> DerefMut for Table<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        self.to_mut()
    }
}

impl<T: bytemuck::Pod> Default for Table<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: bytemuck::Pod> Clone for Table<T> {
    /// An owned table's values are copied; a mapped table shares the mapping.
    fn clone(&self) -> Self {
        Self {
            repr: match &self.repr {
                Repr::Owned(v) => Repr::Owned(v.clone()),
                Repr::Mapped { map, offset, len } => Repr::Mapped {
                    map: map.clone(),
                    offset: *offset,
                    len: *len,
                },
            },
        }
    }
}

impl<T: bytemuck::Pod + fmt::Debug> fmt::Debug for Table<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        <[T] as fmt::Debug>::fmt(self, f)
    }
}

/// Equal values, wherever they live.
impl<T: bytemuck::Pod + PartialEq> PartialEq for Table<T> {
    fn eq(&self, other: &Self) -> bool {
        **self == **other
    }
}

impl<T: bytemuck::Pod> From<Vec<T>> for Table<T> {
    fn from(v: Vec<T>) -> Self {
        Self {
            repr: Repr::Owned(v),
        }
    }
}

impl<T: bytemuck::Pod> FromIterator<T> for Table<T> {
    fn from_iter<I: IntoIterator<Item = T>>(iter: I) -> Self {
        Vec::from_iter(iter).into()
    }
}

impl<'a, T: bytemuck::Pod> IntoIterator for &'a Table<T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}
