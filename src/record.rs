//! Versioned records of the library's state, for learning that survives a power cut.
//!
//! Available with the crate feature `serde`.
//!
//! Every optimizer, its configuration, the [`Adapter`](crate::controller::Adapter) with the
//! controller and cost shaper it holds, [`Bounds`](crate::Bounds) and
//! [`Vector`](crate::Vector) implement `serde`'s `Serialize`/`Deserialize` under the `serde`
//! feature. This module wraps such a value into a self-describing record, encoded with
//! `postcard`:
//!
//! ```text
//! FORMAT_VERSION (varint) | shape (varint count, varint words) | postcard payload | CRC-32 (LE)
//! ```
//!
//! The shape names the type and its const-generic sizes (dimension, population, archive
//! capacities, ...), nested for the types it holds ([`Persistent::SHAPE`]). Loading a record
//! into a value of another type, other sizes or another format version is an error
//! ([`RecordError`]), never a wrong state; so is a record whose checksum (CRC-32/ISCSI over
//! everything before it) does not match. A loaded value continues bit for bit where the saved
//! one stopped, a pending candidate included: save after every `tell` (and, to resume an
//! episode that a power cut interrupted, after every `ask` too), together with the caller's
//! RNG when its state matters (a pair `(A, B)` of persistent values is persistent).
//!
//! The checksum guards against accidental corruption. A record whose checksum is right but
//! whose content is not (a bug in a writer, a crafted hand-over file) is caught by the next
//! check: a decoded value is validated like a constructed one before it is returned
//! ([`Persistent::validate`]: its constructor's range checks plus its internal invariants,
//! such as finite positive step sizes, indices within capacity and an incumbent inside the
//! box), and a value that fails is [`RecordError::Invalid`], naming the field.
//!
//! ```
//! use ctrl_adapt::record::{self, RecordError};
//! use ctrl_adapt::{Bounds, CoordinateConfig, CoordinateSearch, Optimizer, Vector};
//!
//! let bounds = Bounds::<2>::uniform(-1.0, 1.0)?;
//! let mut search = CoordinateSearch::try_new(bounds, Vector::zeros(), CoordinateConfig::DEFAULT)?;
//! # let mut rng = rand_xoshiro::Xoshiro128PlusPlus::seed_from_u64(1);
//! # use rand_core::SeedableRng;
//! let theta = search.ask(&mut rng)?;
//! search.tell(theta.norm_squared())?;
//!
//! let mut buf = [0u8; 256];
//! let bytes = record::save(&search, &mut buf)?;
//! let restored: CoordinateSearch<2> = record::load(bytes)?;
//! assert_eq!(restored, search);
//! // Another dimension is refused.
//! assert_eq!(record::load::<CoordinateSearch<3>>(bytes), Err(RecordError::Shape));
//! # Ok::<(), Box<dyn core::error::Error>>(())
//! ```

use core::fmt;

use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::error::Error;

/// The version of the record layout and of every type's encoding. It changes whenever a
/// saved field is added, removed or reordered, or changes its meaning (8: `RlsModel` saves
/// its covariance as the factors U and D of P = U·D·Uᵀ, without a reset count): a record of
/// another version is refused.
pub const FORMAT_VERSION: u16 = 8;

/// The most words a [`Shape`] holds (a compile-time error beyond).
pub const SHAPE_CAPACITY: usize = 32;

/// Bytes of a record besides its shape and payload, at most: the version (a varint ≤ 3
/// bytes), the shape's word count (1 byte) and the CRC-32 (4 bytes).
pub const OVERHEAD: usize = 8;

const CHECKSUM: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI);

/// A type's name and const-generic sizes, as written into a record's header: a four-byte
/// tag, the sizes, then the shapes of the types it holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Shape {
    words: [u32; SHAPE_CAPACITY],
    len: usize,
}

impl Shape {
    /// No word: the shape of a type that adds nothing to a record (no guard).
    pub const EMPTY: Self = Self {
        words: [0; SHAPE_CAPACITY],
        len: 0,
    };

    /// A type tagged `tag` with the const-generic `sizes`.
    pub const fn new(tag: [u8; 4], sizes: &[usize]) -> Self {
        let mut shape = Self {
            words: [0; SHAPE_CAPACITY],
            len: 0,
        };
        shape = shape.push(u32::from_le_bytes(tag));
        let mut i = 0;
        while i < sizes.len() {
            // Sizes beyond u32 cannot be allocated on the targets; saturate rather than wrap.
            let size = if sizes[i] > u32::MAX as usize {
                u32::MAX
            } else {
                sizes[i] as u32
            };
            shape = shape.push(size);
            i += 1;
        }
        shape
    }

    /// This shape followed by `inner`, the shape of a type held inside.
    pub const fn nest(self, inner: Shape) -> Self {
        let mut shape = self;
        let mut i = 0;
        while i < inner.len {
            shape = shape.push(inner.words[i]);
            i += 1;
        }
        shape
    }

    const fn push(mut self, word: u32) -> Self {
        assert!(
            self.len < SHAPE_CAPACITY,
            "shape longer than SHAPE_CAPACITY"
        );
        self.words[self.len] = word;
        self.len += 1;
        self
    }

    /// The words of the shape.
    pub fn as_slice(&self) -> &[u32] {
        self.words.get(..self.len).unwrap_or(&[])
    }
}

/// A value that can be saved as a record and loaded back.
pub trait Persistent: Serialize + DeserializeOwned {
    /// The type's tag and sizes, nested for the types it holds.
    const SHAPE: Shape;

    /// `Ok` when the value is one its constructors and methods could have produced: the
    /// constructor's range checks and the type's internal invariants, for the types it
    /// holds too. [`load`] calls it on every decoded value, so a record whose checksum is
    /// right but whose content is not (a buggy writer, a crafted file) is refused instead
    /// of misbehaving later. The error names the offending field. A type with no invariant
    /// (an RNG's state) returns `Ok(())`.
    fn validate(&self) -> Result<(), Error>;
}

/// Why a record could not be saved or loaded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum RecordError {
    /// The buffer is too small for the record.
    BufferTooSmall,
    /// The record's checksum does not match: it is truncated or corrupted.
    Corrupt,
    /// The record was written in another format version.
    Version {
        /// The version found in the record.
        found: u16,
    },
    /// The record holds another type, or the same type with other sizes.
    Shape,
    /// The payload does not decode as the expected type (or leaves bytes over).
    Encoding,
    /// The payload decodes but holds a state the type cannot be in (a NaN step size, an
    /// index past its capacity, an incumbent outside the box, ...): the error names the
    /// field ([`Persistent::validate`]).
    Invalid(Error),
}

impl fmt::Display for RecordError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::BufferTooSmall => f.write_str("the buffer is too small for the record"),
            Self::Corrupt => f.write_str("the record's checksum does not match"),
            Self::Version { found } => write!(
                f,
                "the record has format version {found}, this build reads {FORMAT_VERSION}"
            ),
            Self::Shape => f.write_str("the record holds another type or other sizes"),
            Self::Encoding => f.write_str("the record's payload does not decode"),
            Self::Invalid(e) => write!(f, "the record's payload is not a valid state: {e}"),
        }
    }
}

impl core::error::Error for RecordError {}

fn encoding(e: postcard::Error) -> RecordError {
    match e {
        postcard::Error::SerializeBufferFull => RecordError::BufferTooSmall,
        _ => RecordError::Encoding,
    }
}

/// Writes `value` as a record into `buf` and returns the part of `buf` it fills.
///
/// A value that [`load`] would refuse (one that fails [`Persistent::validate`]) is refused
/// here, as [`RecordError::Invalid`], and nothing is written: a record that saves always
/// loads back, equal.
pub fn save<'b, T: Persistent>(value: &T, buf: &'b mut [u8]) -> Result<&'b mut [u8], RecordError> {
    value.validate().map_err(RecordError::Invalid)?;
    save_unchecked(value, buf)
}

/// [`save`] without the validation: the forged records of the tests of `load`'s checks.
pub(crate) fn save_unchecked<'b, T: Persistent>(
    value: &T,
    buf: &'b mut [u8],
) -> Result<&'b mut [u8], RecordError> {
    let body_room = buf
        .len()
        .checked_sub(4)
        .ok_or(RecordError::BufferTooSmall)?;
    let (body, _) = buf.split_at_mut(body_room);
    let header = postcard::to_slice(&(FORMAT_VERSION, T::SHAPE.as_slice()), body)
        .map_err(encoding)?
        .len();
    let rest = body.get_mut(header..).ok_or(RecordError::BufferTooSmall)?;
    let payload = postcard::to_slice(value, rest).map_err(encoding)?.len();
    let end = header + payload;
    let checksum = CHECKSUM.checksum(buf.get(..end).ok_or(RecordError::BufferTooSmall)?);
    let tail = buf
        .get_mut(end..end + 4)
        .ok_or(RecordError::BufferTooSmall)?;
    tail.copy_from_slice(&checksum.to_le_bytes());
    buf.get_mut(..end + 4).ok_or(RecordError::BufferTooSmall)
}

/// Reads a record written by [`save`] for the same type and sizes.
pub fn load<T: Persistent>(bytes: &[u8]) -> Result<T, RecordError> {
    let split = bytes.len().checked_sub(4).ok_or(RecordError::Corrupt)?;
    let (body, tail) = bytes.split_at(split);
    let stored = u32::from_le_bytes(tail.try_into().map_err(|_| RecordError::Corrupt)?);
    if CHECKSUM.checksum(body) != stored {
        return Err(RecordError::Corrupt);
    }
    let (version, rest) =
        postcard::take_from_bytes::<u16>(body).map_err(|_| RecordError::Encoding)?;
    if version != FORMAT_VERSION {
        return Err(RecordError::Version { found: version });
    }
    let (shape, rest) = postcard::take_from_bytes::<heapless::Vec<u32, SHAPE_CAPACITY>>(rest)
        .map_err(|_| RecordError::Shape)?;
    if shape.as_slice() != T::SHAPE.as_slice() {
        return Err(RecordError::Shape);
    }
    match postcard::take_from_bytes::<T>(rest) {
        Ok((value, [])) => value
            .validate()
            .map(|()| value)
            .map_err(RecordError::Invalid),
        _ => Err(RecordError::Encoding),
    }
}

impl<A: Persistent, B: Persistent> Persistent for (A, B) {
    const SHAPE: Shape = Shape::new(*b"PAIR", &[]).nest(A::SHAPE).nest(B::SHAPE);

    fn validate(&self) -> Result<(), Error> {
        self.0.validate()?;
        self.1.validate()
    }
}

/// `serde` for `[T; L]` of any length `L` (serde's own impls stop at 32): a tuple of `L`
/// elements, so postcard writes no length. Used with `#[serde(with = "...")]`.
pub(crate) mod array {
    use core::fmt;
    use core::marker::PhantomData;

    use serde::de::{self, Deserialize, Deserializer, SeqAccess, Visitor};
    use serde::ser::{Serialize, SerializeTuple, Serializer};

    pub(crate) fn serialize<S: Serializer, T: Serialize, const L: usize>(
        array: &[T; L],
        serializer: S,
    ) -> Result<S::Ok, S::Error> {
        let mut tuple = serializer.serialize_tuple(L)?;
        for element in array {
            tuple.serialize_element(element)?;
        }
        tuple.end()
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>, T: Deserialize<'de>, const L: usize>(
        deserializer: D,
    ) -> Result<[T; L], D::Error> {
        struct Elements<T, const L: usize>(PhantomData<T>);

        impl<'de, T: Deserialize<'de>, const L: usize> Visitor<'de> for Elements<T, L> {
            type Value = [T; L];

            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "an array of {L} elements")
            }

            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<[T; L], A::Error> {
                let mut elements = heapless::Vec::<T, L>::new();
                for i in 0..L {
                    let element = seq
                        .next_element()?
                        .ok_or_else(|| de::Error::invalid_length(i, &self))?;
                    // At most L pushes into a capacity of L: cannot fail.
                    elements
                        .push(element)
                        .map_err(|_| de::Error::invalid_length(i, &self))?;
                }
                elements
                    .into_array()
                    .map_err(|e| de::Error::invalid_length(e.len(), &self))
            }
        }

        deserializer.deserialize_tuple(L, Elements::<T, L>(PhantomData))
    }
}

mod shapes {
    use super::{Error, Persistent, Shape};
    use crate::controller::change::ChangeDetector;
    use crate::controller::guard::{Guard, Supervisor, Unguarded};
    use crate::controller::{
        Adapter, Corrected, CorrectedPd, EpisodeRunner, IdentityFeatures, LinearPolicy, Pd,
        PeriodicPd, PeriodicRbf, StateFeatures,
    };
    use crate::cost::{ApexHeightCost, QuadraticCost, SurveyCost};
    use crate::model::{
        Affine, ModelBased, OnlineModel, Regressors, RlsModel, TickModel, Unmodelled,
    };
    use crate::optimizer::{
        AnyOptimizer, Cmaes, ControlledRandomSearch, CoordinateSearch, DiagonalCem, Generation,
        InFlight, LineBo, Optimizer, Racos, Rockstar, Sracos, TwoPhase,
    };
    use crate::{Bounds, Vector};

    /// No guard adds nothing to a record: its shape is empty and it encodes to no byte, so
    /// the records of unguarded adapters are those of the versions before the guard.
    impl Persistent for Unguarded {
        const SHAPE: Shape = Shape::EMPTY;

        fn validate(&self) -> Result<(), Error> {
            Ok(())
        }
    }
    impl<const L: usize, const T: usize> Persistent for Guard<L, T> {
        const SHAPE: Shape = Shape::new(*b"GRD_", &[L, T]);

        /// The configuration's ranges, an envelope without NaN, a running trip's reason a
        /// limit that exists (the state coordinates are checked by the runner holding it).
        fn validate(&self) -> Result<(), Error> {
            <Self as Supervisor<0>>::validate_decoded(self)
        }
    }
    impl Persistent for ChangeDetector {
        const SHAPE: Shape = Shape::new(*b"CHGD", &[]);

        /// The configuration, finite references and statistics, counts that agree
        /// ([`ChangeDetector::validate`]).
        fn validate(&self) -> Result<(), Error> {
            ChangeDetector::validate(self)
        }
    }
    /// No model adds nothing to a record either.
    impl Persistent for Unmodelled {
        const SHAPE: Shape = Shape::EMPTY;

        fn validate(&self) -> Result<(), Error> {
            Ok(())
        }
    }
    impl Persistent for Affine {
        const SHAPE: Shape = Shape::new(*b"AFFN", &[]);

        fn validate(&self) -> Result<(), Error> {
            Ok(())
        }
    }
    impl<const S: usize, const A: usize, const R: usize> Persistent for RlsModel<S, A, R> {
        const SHAPE: Shape = Shape::new(*b"RLSM", &[S, A, R]);

        /// The configuration, finite weights and errors, and covariance factors that prove P
        /// positive definite with its diagonal within the bound ([`RlsModel::validate`]).
        fn validate(&self) -> Result<(), Error> {
            RlsModel::validate(self)
        }
    }
    /// The regressor map `M` is saved with the model (a closure cannot be: give the features
    /// a type).
    impl<M, const S: usize, const A: usize, const R: usize> Persistent for OnlineModel<M, S, A, R>
    where
        M: Persistent + Regressors<S, A, R>,
    {
        const SHAPE: Shape = Shape::new(*b"ONLM", &[S, A, R]).nest(M::SHAPE);

        fn validate(&self) -> Result<(), Error> {
            self.map().validate()?;
            self.validate_decoded()
        }
    }
    impl<F: Persistent + Optimizer<N>, const N: usize> Persistent for ModelBased<F, N> {
        const SHAPE: Shape = Shape::new(*b"MBAS", &[N]).nest(F::SHAPE);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<const N: usize> Persistent for Vector<N> {
        const SHAPE: Shape = Shape::new(*b"VECT", &[N]);

        /// Any vector is a vector.
        fn validate(&self) -> Result<(), Error> {
            Ok(())
        }
    }
    impl<const N: usize> Persistent for Bounds<N> {
        const SHAPE: Shape = Shape::new(*b"BNDS", &[N]);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<const N: usize> Persistent for CoordinateSearch<N> {
        const SHAPE: Shape = Shape::new(*b"CRDS", &[N]);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<O: Persistent + Generation<N>, const N: usize, const C: usize> Persistent
        for InFlight<O, N, C>
    {
        const SHAPE: Shape = Shape::new(*b"FLYT", &[N, C]).nest(O::SHAPE);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<const N: usize, const M: usize> Persistent for ControlledRandomSearch<N, M> {
        const SHAPE: Shape = Shape::new(*b"CRS_", &[N, M]);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<G: Persistent + Optimizer<N>, const N: usize> Persistent for TwoPhase<G, N> {
        const SHAPE: Shape = Shape::new(*b"TWOP", &[N]).nest(G::SHAPE);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<const N: usize, const K: usize, const M: usize> Persistent for Sracos<N, K, M> {
        const SHAPE: Shape = Shape::new(*b"SRAC", &[N, K, M]);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<const N: usize, const K: usize, const M: usize> Persistent for Racos<N, K, M> {
        const SHAPE: Shape = Shape::new(*b"RACO", &[N, K, M]);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<const N: usize, const K: usize, const E: usize> Persistent for DiagonalCem<N, K, E> {
        const SHAPE: Shape = Shape::new(*b"DCEM", &[N, K, E]);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<const N: usize, const L: usize> Persistent for Cmaes<N, L> {
        const SHAPE: Shape = Shape::new(*b"CMAE", &[N, L]);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<const N: usize, const M: usize> Persistent for Rockstar<N, M> {
        const SHAPE: Shape = Shape::new(*b"ROCK", &[N, M]);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<const N: usize, const M: usize> Persistent for LineBo<N, M> {
        const SHAPE: Shape = Shape::new(*b"LNBO", &[N, M]);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<const N: usize, const L: usize, const E: usize, const M: usize, const G: usize> Persistent
        for AnyOptimizer<N, L, E, M, G>
    {
        const SHAPE: Shape = Shape::new(*b"ANYO", &[N, L, E, M, G]);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<const A: usize> Persistent for Pd<A> {
        const SHAPE: Shape = Shape::new(*b"PD__", &[A]);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl Persistent for IdentityFeatures {
        const SHAPE: Shape = Shape::new(*b"IDFE", &[]);

        /// Any vector is a vector.
        fn validate(&self) -> Result<(), Error> {
            Ok(())
        }
    }
    impl<const S: usize> Persistent for StateFeatures<S> {
        const SHAPE: Shape = Shape::new(*b"STFE", &[S]);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<const K: usize> Persistent for PeriodicRbf<K> {
        const SHAPE: Shape = Shape::new(*b"PRBF", &[K]);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<const C: usize, const F: usize, M: Persistent> Persistent for LinearPolicy<C, F, M> {
        const SHAPE: Shape = Shape::new(*b"LINP", &[C, F]).nest(M::SHAPE);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<const A: usize, const S: usize, const F: usize, const P: usize, M: Persistent> Persistent
        for CorrectedPd<A, S, F, P, M>
    {
        const SHAPE: Shape = Shape::new(*b"CPD_", &[A, S, F, P]).nest(M::SHAPE);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    /// Your nominal law `N` is saved with it (its `Persistent` impl is yours; a closure
    /// cannot be saved: give the law a type).
    impl<N: Persistent, const A: usize, const S: usize, const P: usize> Persistent
        for Corrected<N, A, S, P>
    {
        const SHAPE: Shape = Shape::new(*b"CORR", &[A, S, P]).nest(N::SHAPE);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<const K: usize, const P: usize> Persistent for PeriodicPd<K, P> {
        const SHAPE: Shape = Shape::new(*b"PPD_", &[K, P]);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl Persistent for SurveyCost {
        const SHAPE: Shape = Shape::new(*b"SURV", &[]);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<const K: usize> Persistent for QuadraticCost<K> {
        const SHAPE: Shape = Shape::new(*b"QUAD", &[K]);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl Persistent for ApexHeightCost {
        const SHAPE: Shape = Shape::new(*b"APEX", &[]);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<C, Sh, const P: usize, const S: usize, const A: usize, G, M> Persistent
        for EpisodeRunner<C, Sh, P, S, A, G, M>
    where
        C: Persistent,
        Sh: Persistent,
        G: Persistent + Supervisor<S>,
        M: Persistent + TickModel<S, A>,
    {
        const SHAPE: Shape = Shape::new(*b"RUNR", &[P, S, A])
            .nest(C::SHAPE)
            .nest(Sh::SHAPE)
            .nest(G::SHAPE)
            .nest(M::SHAPE);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
    impl<O, C, Sh, const P: usize, const S: usize, const A: usize, G, M> Persistent
        for Adapter<O, C, Sh, P, S, A, G, M>
    where
        O: Persistent + Optimizer<P>,
        C: Persistent,
        Sh: Persistent,
        G: Persistent + Supervisor<S>,
        M: Persistent + TickModel<S, A>,
    {
        const SHAPE: Shape = Shape::new(*b"ADPT", &[P, S, A])
            .nest(O::SHAPE)
            .nest(C::SHAPE)
            .nest(Sh::SHAPE)
            .nest(G::SHAPE)
            .nest(M::SHAPE);

        fn validate(&self) -> Result<(), Error> {
            self.check_decoded()
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec::Vec;

    use rand_core::RngCore;
    use rand_xoshiro::Xoshiro128PlusPlus;

    use super::*;
    use crate::model::{
        Affine, ModelBased, ModelBasedConfig, ModelConfig, OnlineModel, RlsModel, Source, TickModel,
    };
    use crate::optimizer::{
        AnyOptimizer, CemConfig, Cmaes, CmaesConfig, ControlledRandomSearch, CoordinateConfig,
        CoordinateSearch, CrsConfig, DiagonalCem, LineBo, LineBoConfig, LineDirections, Optimizer,
        Racos, Rockstar, RockstarConfig, Sracos, SracosConfig, Suppression, TwoPhase,
    };
    use crate::random::unit_f32;
    use crate::testing::rng;
    use crate::{Bounds, Vector};

    impl Persistent for Xoshiro128PlusPlus {
        const SHAPE: Shape = Shape::new(*b"XO++", &[]);

        /// Any state of the generator is one.
        fn validate(&self) -> Result<(), Error> {
            Ok(())
        }
    }

    /// A noisy shifted sphere; the noise comes from the caller's RNG, so a resumed run is
    /// identical only if the RNG was saved with the optimizer.
    fn cost<const N: usize>(theta: &Vector<N>, r: &mut Xoshiro128PlusPlus) -> f32 {
        (theta - Vector::repeat(0.3)).norm_squared() + 0.01 * unit_f32(r)
    }

    type Event = (Vec<u32>, u32);

    fn event<const N: usize>(theta: &Vector<N>, cost: f32) -> Event {
        (theta.iter().map(|v| v.to_bits()).collect(), cost.to_bits())
    }

    /// Up to `total` ask/tell steps of `s` from `step` on; the events, and the state after.
    fn run<const N: usize, O: Optimizer<N>>(
        s: &mut O,
        r: &mut Xoshiro128PlusPlus,
        steps: usize,
    ) -> Vec<Event> {
        let mut events = Vec::new();
        for _ in 0..steps {
            let Ok(theta) = s.ask(r) else { break };
            let c = cost(&theta, r);
            s.tell(c).unwrap();
            events.push(event(&theta, c));
        }
        events
    }

    fn bytes<T: Persistent>(value: &T) -> Vec<u8> {
        let mut buf = std::vec![0u8; 1 << 16];
        save(value, &mut buf).unwrap().to_vec()
    }

    /// Runs `fresh` for `total` steps uninterrupted, then again saved and loaded (with the
    /// RNG) after each of `cuts` steps, once between a tell and the next ask and once with a
    /// candidate pending; the resumed runs must match the uninterrupted one bit for bit:
    /// every candidate, every cost, the best and the final state's record.
    fn check_resumes_bit_identically<const N: usize, O>(fresh: O, total: usize, cuts: &[usize])
    where
        O: Optimizer<N> + Persistent + Clone + PartialEq + core::fmt::Debug,
    {
        let mut reference = fresh.clone();
        let mut r = rng(11);
        let expected = run(&mut reference, &mut r, total);
        assert!(expected.len() > cuts.iter().copied().max().unwrap_or(0));
        for &k in cuts {
            for pending in [false, true] {
                let mut s = fresh.clone();
                let mut r = rng(11);
                let mut events = run(&mut s, &mut r, k);
                let asked = pending.then(|| s.ask(&mut r).unwrap());
                let record = bytes(&(s.clone(), r.clone()));
                let (mut s2, mut r2): (O, Xoshiro128PlusPlus) = load(&record).unwrap();
                assert_eq!(s2, s, "k = {k}");
                assert_eq!(bytes(&s2), bytes(&s));
                if let Some(theta) = asked {
                    assert_eq!(s2.pending(), Some(&theta));
                    let c = cost(&theta, &mut r2);
                    s2.tell(c).unwrap();
                    events.push(event(&theta, c));
                }
                events.extend(run(&mut s2, &mut r2, total - events.len()));
                assert_eq!(events, expected, "k = {k}, pending = {pending}");
                assert_eq!(bytes(&s2), bytes(&reference), "k = {k}");
                let (b1, b2) = (s2.best().unwrap(), reference.best().unwrap());
                assert_eq!(b1.cost.to_bits(), b2.cost.to_bits());
                assert_eq!(b1.theta, b2.theta);
            }
        }
    }

    fn bounds<const N: usize>() -> Bounds<N> {
        Bounds::uniform(-1.0, 1.0).unwrap()
    }

    const CUTS: [usize; 5] = [0, 1, 5, 17, 40];

    /// Coordinate search resumes bit for bit after a save and load at any point.
    #[test]
    fn coordinate_search_resumes() {
        let s =
            CoordinateSearch::<3>::try_new(bounds(), Vector::zeros(), CoordinateConfig::DEFAULT)
                .unwrap();
        check_resumes_bit_identically(s, 60, &CUTS);
    }

    /// Controlled random search (M = 40, beyond serde's own arrays) resumes bit for bit.
    #[test]
    fn controlled_random_search_resumes() {
        let s = ControlledRandomSearch::<3, 40>::try_new(bounds(), CrsConfig::DEFAULT).unwrap();
        check_resumes_bit_identically(s, 80, &CUTS);
    }

    /// The two-phase search resumes bit for bit across its hand-over.
    #[test]
    fn two_phase_resumes() {
        let global =
            ControlledRandomSearch::<2, 10>::try_new(bounds(), CrsConfig::DEFAULT).unwrap();
        let s = TwoPhase::try_new(global, 20, CoordinateConfig::DEFAULT).unwrap();
        check_resumes_bit_identically(s, 60, &[0, 5, 19, 20, 21, 40]);
    }

    /// SRACOS (with value suppression, archive M = 40) and RACOS resume bit for bit.
    #[test]
    fn sracos_and_racos_resume() {
        let config = SracosConfig {
            suppression: Some(Suppression {
                non_update_allowed: 3,
                resample_times: 2,
                balance_rate: 0.5,
            }),
            ..SracosConfig::DEFAULT
        };
        let s = Sracos::<4, 3, 40>::try_new(bounds(), config).unwrap();
        check_resumes_bit_identically(s, 80, &CUTS);
        let s = Sracos::<4>::try_new(bounds(), SracosConfig::DEFAULT).unwrap();
        check_resumes_bit_identically(s, 60, &CUTS);
        let s = Racos::<4, 2, 34>::try_new(bounds(), SracosConfig::DEFAULT).unwrap();
        check_resumes_bit_identically(s, 100, &CUTS);
    }

    /// Diagonal CEM resumes bit for bit, mid-batch and at a batch boundary.
    #[test]
    fn diagonal_cem_resumes() {
        let s =
            DiagonalCem::<3, 8, 4>::try_new(bounds(), Vector::zeros(), CemConfig::DEFAULT).unwrap();
        check_resumes_bit_identically(s, 60, &[0, 1, 7, 8, 9, 40]);
    }

    /// CMA-ES (population 36, beyond serde's own arrays; active) resumes bit for bit.
    #[test]
    fn cmaes_resumes() {
        let config = CmaesConfig {
            active: true,
            eigen_interval: 2,
            ..CmaesConfig::DEFAULT
        };
        let s = Cmaes::<3, 36>::try_new(bounds(), Vector::zeros(), config).unwrap();
        check_resumes_bit_identically(s, 120, &[0, 1, 35, 36, 37, 80]);
        let s = Cmaes::<4, 7>::try_new(bounds(), Vector::zeros(), CmaesConfig::DEFAULT).unwrap();
        check_resumes_bit_identically(s, 60, &CUTS);
    }

    /// ROCK* (memory M = 40) resumes bit for bit.
    #[test]
    fn rockstar_resumes() {
        let s =
            Rockstar::<3, 40>::try_new(bounds(), Vector::zeros(), RockstarConfig::DEFAULT).unwrap();
        check_resumes_bit_identically(s, 60, &CUTS);
    }

    /// LineBO (capacity 12, so the GP evicts from the 13th episode on) resumes bit for bit,
    /// with random lines (the RNG is saved with it) and with a threshold, cut inside a
    /// line, at its end and after eviction began.
    #[test]
    fn line_bo_resumes() {
        let config = LineBoConfig {
            directions: LineDirections::Random,
            threshold: Some(1.0),
            ..LineBoConfig::DEFAULT
        };
        let s = LineBo::<3, 12>::try_new(bounds(), Vector::zeros(), config).unwrap();
        check_resumes_bit_identically(s, 40, &[0, 1, 3, 4, 12, 13, 25]);
    }

    /// The enum over the algorithms resumes bit for bit in each variant.
    #[test]
    fn any_optimizer_resumes() {
        let s: AnyOptimizer<3, 7, 3, 10> =
            Cmaes::try_new(bounds(), Vector::zeros(), CmaesConfig::DEFAULT)
                .unwrap()
                .into();
        check_resumes_bit_identically(s, 40, &[3, 20]);
        let s: AnyOptimizer<3, 7, 3, 10> = Sracos::try_new(bounds(), SracosConfig::DEFAULT)
            .unwrap()
            .into();
        check_resumes_bit_identically(s, 40, &[3, 20]);
    }

    /// One coordinate's interval: ordinary, narrow relative to its offset (down to a few
    /// ulps: [100, 100.001] and the like), or very wide (up to 10³⁰).
    fn any_interval() -> impl proptest::strategy::Strategy<Value = (f32, f32)> {
        use proptest::prelude::*;
        prop_oneof![
            (-1e3f32..1e3, 1e-2f32..1e3).prop_map(|(lo, w)| (lo, lo + w)),
            (1f32..1e6, any::<bool>(), 2.0f32..8.0).prop_map(|(m, negative, e)| {
                let lo = if negative { -m } else { m };
                let hi = lo + m * libm::powf(10.0, -e);
                (lo, if hi > lo { hi } else { lo.next_up() })
            }),
            (-1e3f32..1e3, 0.0f32..30.0).prop_map(|(lo, e)| (lo, lo + libm::powf(10.0, e))),
        ]
    }

    /// A box of [`any_interval`]s and a start inside it.
    fn any_box_and_start<const N: usize>()
    -> impl proptest::strategy::Strategy<Value = (Bounds<N>, Vector<N>)> {
        use proptest::prelude::*;
        (
            prop::array::uniform::<_, N>(any_interval()),
            prop::array::uniform::<_, N>(0.0f32..=1.0),
        )
            .prop_map(|(intervals, frac)| {
                let bounds = Bounds::try_new(
                    Vector::from(intervals.map(|(lo, _)| lo)),
                    Vector::from(intervals.map(|(_, hi)| hi)),
                )
                .unwrap();
                let start = Vector::from_fn(|i, _| {
                    let (lo, hi) = (bounds.lower()[i], bounds.upper()[i]);
                    (lo + frac[i] * (hi - lo)).clamp(lo, hi)
                });
                (bounds, start)
            })
    }

    /// `steps` ask/tell steps of `s` on a finite cost of the box's unit coordinates, then
    /// (if `pending`) one more ask; the state must save, load back equal and save again to
    /// the same bytes.
    fn check_reloads<const N: usize, O>(mut s: O, steps: usize, pending: bool, seed: u64)
    where
        O: Optimizer<N> + Persistent + PartialEq + core::fmt::Debug,
    {
        let mut r = rng(seed);
        let (lower, upper) = (*s.bounds().lower(), *s.bounds().upper());
        for _ in 0..steps {
            let Ok(theta) = s.ask(&mut r) else { break };
            let c: f64 = (0..N)
                .map(|i| {
                    let u = (f64::from(theta[i]) - f64::from(lower[i]))
                        / (f64::from(upper[i]) - f64::from(lower[i]));
                    (u - 0.3).powi(2)
                })
                .sum();
            s.tell(c as f32 + 0.01 * unit_f32(&mut r)).unwrap();
        }
        if pending {
            let _ = s.ask(&mut r);
        }
        let record = bytes(&s);
        let loaded: O = load(&record).unwrap_or_else(|e| panic!("{e:?} for {s:?}"));
        assert_eq!(loaded, s);
        assert_eq!(bytes(&loaded), record);
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(96))]

        /// Any state reachable through the public API saves and loads back bit-identical,
        /// for every optimizer, over boxes ordinary, narrow relative to their offset and
        /// very wide, with and without a candidate pending.
        #[test]
        fn every_optimizer_reloads_on_any_box(
            (bounds, start) in any_box_and_start::<2>(),
            steps in 0usize..14,
            pending: bool,
            seed: u64,
        ) {
            let coordinate = CoordinateConfig::DEFAULT;
            check_reloads(CoordinateSearch::try_new(bounds, start, coordinate).unwrap(), steps, pending, seed);
            let crs = || ControlledRandomSearch::<2, 6>::try_new(bounds, CrsConfig::DEFAULT).unwrap();
            check_reloads(crs(), steps, pending, seed);
            check_reloads(TwoPhase::try_new(crs(), 8, coordinate).unwrap(), steps, pending, seed);
            check_reloads(Sracos::<2, 2, 8>::try_new(bounds, SracosConfig::DEFAULT).unwrap(), steps, pending, seed);
            check_reloads(Racos::<2, 2, 8>::try_new(bounds, SracosConfig::DEFAULT).unwrap(), steps, pending, seed);
            check_reloads(DiagonalCem::<2, 4, 2>::try_new(bounds, start, CemConfig::DEFAULT).unwrap(), steps, pending, seed);
            check_reloads(Cmaes::<2, 4>::try_new(bounds, start, CmaesConfig::DEFAULT).unwrap(), steps, pending, seed);
            check_reloads(Rockstar::<2, 8>::try_new(bounds, start, RockstarConfig::DEFAULT).unwrap(), steps, pending, seed);
            for directions in [LineDirections::Coordinate, LineDirections::Random] {
                let config = LineBoConfig { directions, threshold: Some(0.5), ..LineBoConfig::DEFAULT };
                check_reloads(LineBo::<2, 6>::try_new(bounds, start, config).unwrap(), steps, pending, seed);
            }
        }
    }

    /// `steps` real episodes of a model-based learner on `bounds` (the first one recorded as
    /// the bare controller's, at the start): each proposal searched by a CMA-ES on the trust
    /// box against a "model" that is the real cost slightly off, the real cost noisy from
    /// the RNG. The events: θ, where it came from and the cost told.
    /// The real cost of θ in `bounds`: a sphere of the box's unit coordinates.
    fn unit_cost<const N: usize>(bounds: &Bounds<N>, t: &Vector<N>) -> f32 {
        let (lower, upper) = (bounds.lower(), bounds.upper());
        let c: f64 = (0..N)
            .map(|i| {
                let u = (f64::from(t[i]) - f64::from(lower[i]))
                    / (f64::from(upper[i]) - f64::from(lower[i]));
                (u - 0.3).powi(2)
            })
            .sum();
        c as f32
    }

    /// The inner search of [`run_model_based`]: a CMA-ES of 16 predictions.
    fn model_inner<const N: usize>(b: Bounds<N>, start: Vector<N>) -> Result<Cmaes<N, 4>, Error> {
        let config = CmaesConfig {
            max_evaluations: 16,
            ..CmaesConfig::DEFAULT
        };
        Cmaes::try_new(b, start, config)
    }

    /// One proposal of [`run_model_based`]: its "model" is the real cost slightly off.
    fn model_propose<const N: usize>(
        l: &mut ModelBased<CoordinateSearch<N>, N>,
        r: &mut Xoshiro128PlusPlus,
    ) -> Result<crate::model::Proposal<N>, Error> {
        let bounds = *l.fallback().bounds();
        l.propose(r, model_inner, |t| Ok(1.1 * unit_cost(&bounds, t) - 0.01))
    }

    /// `steps` real episodes of a model-based learner (the first one recorded as the bare
    /// controller's, at the box's lower corner, and made the screen's reference): each
    /// proposal searched by [`model_inner`] on the trust box, the real cost noisy from the
    /// RNG. The events: θ, the cost told and the prediction (`None` from the fallback).
    fn run_model_based<const N: usize>(
        l: &mut ModelBased<CoordinateSearch<N>, N>,
        r: &mut Xoshiro128PlusPlus,
        steps: usize,
    ) -> Vec<(Event, Option<u32>)> {
        let bounds = *l.fallback().bounds();
        let unit = |t: &Vector<N>| unit_cost(&bounds, t);
        let mut events = Vec::new();
        for _ in 0..steps {
            if l.evaluations() == 0 && l.pending().is_none() {
                let start = *l.fallback().bounds().lower();
                let c = unit(&start) + 0.01 * unit_f32(r);
                l.record(start, c).unwrap();
                l.set_reference(c).unwrap();
                events.push((event(&start, c), None));
                continue;
            }
            let Ok(p) = model_propose(l, r) else {
                break;
            };
            let c = unit(&p.theta) + 0.01 * unit_f32(r);
            l.tell(c).unwrap();
            let source = match p.source {
                Source::Model(predicted) => Some(predicted.to_bits()),
                Source::Fallback => None,
            };
            events.push((event(&p.theta, c), source));
        }
        events
    }

    fn model_based<const N: usize>(
        bounds: Bounds<N>,
        start: Vector<N>,
    ) -> ModelBased<CoordinateSearch<N>, N> {
        let fallback = CoordinateSearch::try_new(bounds, start, CoordinateConfig::DEFAULT).unwrap();
        let config = ModelBasedConfig {
            initial_radius: 0.375,
            inner_evaluations: 16,
            ..ModelBasedConfig::DEFAULT
        };
        ModelBased::try_new(bounds, fallback, config).unwrap()
    }

    /// The model-based learner resumes bit for bit from a record of it and the RNG, saved
    /// between episodes and with a proposal pending (a model's candidate or the fallback's).
    #[test]
    fn model_based_resumes() {
        let fresh = model_based::<3>(bounds(), Vector::zeros());
        let total = 30;
        let mut reference = fresh;
        let expected = run_model_based(&mut reference, &mut rng(11), total);
        assert!(expected.iter().any(|(_, s)| s.is_some()));
        assert!(expected.iter().skip(1).any(|(_, s)| s.is_none()));
        for k in [0usize, 1, 2, 7, 20] {
            for pending in [false, true] {
                let mut l = fresh;
                let mut r = rng(11);
                let mut events = run_model_based(&mut l, &mut r, k);
                if pending && k > 0 {
                    model_propose(&mut l, &mut r).unwrap();
                }
                let record = bytes(&(l, r.clone()));
                let (mut l2, mut r2): (ModelBased<CoordinateSearch<3>, 3>, Xoshiro128PlusPlus) =
                    load(&record).unwrap();
                assert_eq!(l2, l, "k = {k}");
                assert_eq!(bytes(&l2), bytes(&l));
                events.extend(run_model_based(&mut l2, &mut r2, total - events.len()));
                assert_eq!(events, expected, "k = {k}, pending = {pending}");
                assert_eq!(bytes(&l2), bytes(&reference), "k = {k}");
            }
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

        /// Any state of the model-based learner reachable through its API saves and loads
        /// back bit-identical, over boxes ordinary, narrow and very wide, with and without a
        /// proposal pending.
        #[test]
        fn model_based_reloads_on_any_box(
            (bounds, start) in any_box_and_start::<2>(),
            steps in 0usize..8,
            pending: bool,
            seed: u64,
        ) {
            let mut l = model_based(bounds, start);
            let mut r = rng(seed);
            run_model_based(&mut l, &mut r, steps);
            if pending {
                let _ = model_propose(&mut l, &mut r);
            }
            let record = bytes(&l);
            let loaded: ModelBased<CoordinateSearch<2>, 2> = load(&record).unwrap();
            proptest::prop_assert_eq!(loaded, l);
            proptest::prop_assert_eq!(bytes(&loaded), record);
        }

        /// Any model reachable by fitting ticks (finite, huge or not finite, refused or not)
        /// saves and loads back bit-identical, alone and fed by an adapter's runner.
        #[test]
        fn rls_model_reloads_after_any_ticks(
            ticks in proptest::collection::vec(proptest::array::uniform5(
                proptest::prop_oneof![
                    4 => -10.0f32..10.0,
                    1 => proptest::num::f32::ANY,
                    1 => proptest::strategy::Just(f32::MAX),
                    1 => proptest::strategy::Just(1e20f32),
                ]), 0..40),
            forgetting in 0.5f32..=1.0,
        ) {
            let config = ModelConfig { forgetting, ..ModelConfig::DEFAULT };
            let mut model = RlsModel::<2, 1, 4>::try_new(config).unwrap();
            let mut fed = OnlineModel::new(model, Affine);
            for (k, t) in ticks.iter().enumerate() {
                let (x, u) = (Vector::<2>::new(t[0], t[1]), Vector::<1>::new(t[2]));
                let _ = model.update(&Affine, &x, &u, &Vector::<2>::new(t[3], t[4]));
                if k % 9 == 0 {
                    fed.begin();
                }
                fed.tick(&x, &u);
            }
            let record = bytes(&model);
            let loaded: RlsModel<2, 1, 4> = load(&record).unwrap();
            proptest::prop_assert_eq!(loaded, model);
            proptest::prop_assert_eq!(bytes(&loaded), record);
            let record = bytes(&fed);
            let loaded: OnlineModel<Affine, 2, 1, 4> = load(&record).unwrap();
            proptest::prop_assert_eq!(loaded, fed);
            proptest::prop_assert_eq!(bytes(&loaded), record);
        }
    }

    /// One call of the model-based learner's API with arbitrary arguments.
    #[derive(Debug, Clone)]
    enum Call {
        /// `propose`, its predictions cycling through these (a NaN bit pattern as an error).
        Propose(Vec<f32>),
        Tell(f32),
        Record([f32; 2], f32),
        Reference(f32),
    }

    fn any_call() -> impl proptest::strategy::Strategy<Value = Call> {
        use proptest::prelude::*;
        let f = || {
            prop_oneof![
                3 => -10.0f32..10.0,
                1 => proptest::num::f32::ANY,
                1 => Just(f32::MAX),
                1 => Just(f32::NAN),
            ]
        };
        prop_oneof![
            3 => proptest::collection::vec(f(), 1..6).prop_map(Call::Propose),
            3 => f().prop_map(Call::Tell),
            1 => ([f(), f()], f()).prop_map(|(t, c)| Call::Record(t, c)),
            1 => f().prop_map(Call::Reference),
        ]
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(128))]

        /// The learner's propose / tell / record / set_reference in any order with any f32
        /// (a fuzz of its API): no panic; proposals inside the box; a refused call changes
        /// nothing; after every call the state saves and loads back bit-identical.
        #[test]
        fn model_based_survives_any_call_sequence(
            calls in proptest::collection::vec(any_call(), 1..24),
            seed: u64,
        ) {
            let mut l = model_based::<2>(bounds(), Vector::zeros());
            let mut r = rng(seed);
            for call in &calls {
                let before = l;
                let refused = match call {
                    Call::Propose(predictions) => {
                        let mut k = 0;
                        let p = l.propose(&mut r, model_inner, |_| {
                            k += 1;
                            let c = predictions[k % predictions.len()];
                            if c.is_nan() { Err(Error::NonFinite("prediction")) } else { Ok(c) }
                        });
                        if let Ok(p) = p {
                            proptest::prop_assert!(l.fallback().bounds().contains(&p.theta));
                            proptest::prop_assert_eq!(l.pending(), Some(&p));
                        }
                        false
                    }
                    Call::Tell(c) => l.tell(*c).is_err(),
                    Call::Record(t, c) => l.record(Vector::from(*t), *c).is_err(),
                    Call::Reference(c) => l.set_reference(*c).is_err(),
                };
                if refused {
                    proptest::prop_assert_eq!(l, before);
                }
                let record = bytes(&l);
                let loaded: ModelBased<CoordinateSearch<2>, 2> = load(&record).unwrap();
                proptest::prop_assert_eq!(loaded, l);
                proptest::prop_assert_eq!(bytes(&loaded), record);
            }
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

        /// A learner with a restart, told any costs around its bare cost, saves and loads
        /// back bit-identical after every episode, its stall count and restarts included.
        #[test]
        fn a_restarting_model_based_learner_reloads_after_any_episodes(
            costs in proptest::collection::vec(-1.0f32..4.0, 1..30),
            restart_after in 1u32..4,
            seed: u64,
        ) {
            let l = model_based::<2>(bounds(), Vector::zeros());
            let config = ModelBasedConfig { restart_after, ..*l.config() };
            let mut l = ModelBased::try_new(bounds(), *l.fallback(), config).unwrap();
            l.record(Vector::zeros(), 0.0).unwrap();
            let mut r = rng(seed);
            for c in costs {
                if model_propose(&mut l, &mut r).is_err() {
                    break;
                }
                l.tell(c).unwrap();
                let record = bytes(&l);
                let loaded: ModelBased<CoordinateSearch<2>, 2> = load(&record).unwrap();
                proptest::prop_assert_eq!(loaded, l);
                proptest::prop_assert_eq!(bytes(&loaded), record);
            }
        }
    }

    /// Checks: a change detector saves and loads back bit-identical after every episode, in
    /// each phase (measuring its reference, steady, alarmed); its decoded-state checks are
    /// tested in its module.
    #[test]
    fn change_detectors_round_trip_and_are_validated() {
        use crate::controller::change::{ChangeConfig, ChangeDetector};
        let mut detector = ChangeDetector::try_new(ChangeConfig::DEFAULT).unwrap();
        let costs = (0..40).map(|k| 1.0 + 0.01 * ((k * 7 % 11) as f32 - 5.0));
        let costs = costs.chain([1.5, 1.6, 1.7, 1.8, 1.9, 2.0, 2.1, 2.2]);
        let mut seen_alarm = false;
        for (k, cost) in costs.enumerate() {
            detector.observe(cost, Some(0.1)).unwrap();
            let record = bytes(&detector);
            let loaded: ChangeDetector = load(&record).unwrap();
            assert_eq!(loaded, detector, "after episode {k}");
            assert_eq!(bytes(&loaded), record);
            seen_alarm |= detector.changed();
        }
        assert!(seen_alarm, "a rise of 50 to 120 % is a change");
    }

    /// Checks: a decoded model or learner whose checksum is right but whose content is not
    /// is refused naming the field: a NaN or too large variance, covariance factors that are
    /// not a positive definite P within its bound, a radius beyond its bounds, a model
    /// candidate with a NaN prediction.
    #[test]
    fn decoded_models_and_learners_are_validated() {
        let mut model = RlsModel::<2, 1, 4>::try_new(ModelConfig::DEFAULT).unwrap();
        let refused = |forged: Vec<u8>| load::<RlsModel<2, 1, 4>>(&forged).unwrap_err();
        let record = bytes(&model);
        // The prior variance 100 is the configuration's, then the diagonal's.
        assert_eq!(
            refused(forge_value(&record, 100.0, 1, f32::NAN)),
            RecordError::Invalid(Error::NonFinite("covariance"))
        );
        assert_eq!(
            refused(forge_value(&record, 100.0, 2, 2e4)),
            RecordError::Invalid(Error::InvalidParameter("covariance"))
        );
        let mut x = Vector::<2>::zeros();
        for k in 0..20 {
            let u = Vector::<1>::new(((k * 7) % 5) as f32 - 2.0);
            let next = Vector::<2>::new(x[0] + 0.1 * x[1], 0.9 * x[1] + 0.2 * u[0]);
            model.update(&Affine, &x, &u, &next).unwrap();
            x = next;
        }
        let record = bytes(&model);
        assert_eq!(load::<RlsModel<2, 1, 4>>(&record), Ok(model));
        // The covariance is saved as its factors P = U·D·Uᵀ: a negative D, or an entry of U
        // that takes P's diagonal past its bound, would not be a positive definite P within
        // the bound.
        let (factor, variances) = model.covariance_factors();
        let d = variances[0];
        assert_eq!(
            refused(forge_value(&record, d, 0, -d)),
            RecordError::Invalid(Error::InvalidParameter("covariance"))
        );
        let u = factor[(0, 1)];
        assert_eq!(
            refused(forge_value(&record, u, 0, 1e30)),
            RecordError::Invalid(Error::InvalidParameter("covariance"))
        );

        let mut l = model_based::<2>(bounds(), Vector::zeros());
        run_model_based(&mut l, &mut rng(4), 3);
        let p = l
            .propose(&mut rng(5), model_inner, |t| Ok(t.norm_squared() - 10.0))
            .unwrap();
        let Source::Model(predicted) = p.source else {
            panic!("the model's candidate passes the screen: {p:?}")
        };
        let record = bytes(&l);
        type Learner = ModelBased<CoordinateSearch<2>, 2>;
        assert_eq!(load::<Learner>(&record), Ok(l));
        let refused = |forged: Vec<u8>| load::<Learner>(&forged).unwrap_err();
        // The radius follows the configuration's (its initial value 0.375 there).
        let radius = l.radius();
        let nth = if radius == 0.375 { 1 } else { 0 };
        assert_eq!(
            refused(forge_value(&record, radius, nth, 5.0)),
            RecordError::Invalid(Error::InvalidParameter("radius"))
        );
        assert_eq!(
            refused(forge_value(&record, predicted, 0, f32::NAN)),
            RecordError::Invalid(Error::NonFinite("pending"))
        );
    }

    /// A learner with the candidate-dependent bound, a bounded proposal pending, reloads
    /// equal; a record whose `uncertainty_weight` is forged negative or NaN is refused.
    #[test]
    fn a_bounded_model_based_learner_reloads_and_its_weight_is_checked() {
        use crate::model::Prediction;
        let bounds = Bounds::<2>::uniform(-5.0, 5.0).unwrap();
        let fallback =
            CoordinateSearch::try_new(bounds, Vector::zeros(), CoordinateConfig::DEFAULT).unwrap();
        let config = ModelBasedConfig {
            inner_evaluations: 16,
            uncertainty_weight: 0.8125,
            ..ModelBasedConfig::DEFAULT
        };
        let mut l = ModelBased::try_new(bounds, fallback, config).unwrap();
        l.record(Vector::zeros(), 0.0).unwrap();
        l.propose_bounded(&mut rng(6), model_inner, |t| {
            Ok(Prediction {
                cost: -t.norm_squared(),
                uncertainty: t.norm(),
            })
        })
        .unwrap();
        type Learner = ModelBased<CoordinateSearch<2>, 2>;
        let record = bytes(&l);
        assert_eq!(load::<Learner>(&record), Ok(l));
        for bad in [-1.0, f32::NAN] {
            assert_eq!(
                load::<Learner>(&forge_value(&record, 0.8125, 0, bad)).unwrap_err(),
                RecordError::Invalid(Error::InvalidParameter("uncertainty_weight"))
            );
        }
    }

    /// A learner whose trust region has restarted once and has stalled twice since (its
    /// `restart_after` 3) reloads bit-identical and continues identically; a record whose
    /// stall count is forged to `restart_after`, whose restarts outnumber its episodes, or
    /// whose `restart_after` is forged to 0 beside a restart, is refused naming the field.
    /// The payload is the learner's fields in order: the configuration first (its
    /// `restart_after` 37 bytes after the start of `initial_radius`: six f32, a one-byte
    /// varint, three f32), the stall count and the restarts last (one-byte varints before
    /// the CRC).
    #[test]
    fn a_restarted_model_based_learner_reloads_and_its_counts_are_checked() {
        type Learner = ModelBased<CoordinateSearch<2>, 2>;
        let config = ModelBasedConfig {
            initial_radius: 0.375,
            inner_evaluations: 16,
            restart_after: 3,
            ..ModelBasedConfig::DEFAULT
        };
        let fallback =
            CoordinateSearch::try_new(bounds(), Vector::zeros(), CoordinateConfig::DEFAULT)
                .unwrap();
        let mut l: Learner = ModelBased::try_new(bounds(), fallback, config).unwrap();
        l.record(Vector::zeros(), 0.0).unwrap();
        let mut r = rng(12);
        // Four episodes down to the minimum radius (0.375 × 0.6⁴ < 0.05), three stalled
        // there (a restart), four down again and two stalled: none beats the bare cost 0.
        for _ in 0..13 {
            model_propose(&mut l, &mut r).unwrap();
            l.tell(1.0).unwrap();
        }
        assert_eq!((l.restarts(), l.stalled(), l.evaluations()), (1, 2, 14));
        let record = bytes(&l);
        let mut loaded: Learner = load(&record).unwrap();
        assert_eq!(loaded, l);
        assert_eq!(bytes(&loaded), record);
        // The third stalled episode restarts both alike.
        let mut r2 = r.clone();
        model_propose(&mut l, &mut r).unwrap();
        l.tell(1.0).unwrap();
        model_propose(&mut loaded, &mut r2).unwrap();
        loaded.tell(1.0).unwrap();
        assert_eq!(
            (loaded.restarts(), loaded.stalled(), loaded.radius()),
            (2, 0, 0.375)
        );
        assert_eq!(bytes(&loaded), bytes(&l));

        let end = record.len() - 4;
        assert_eq!(
            record[end - 2..end],
            [2, 1],
            "the stall count and the restarts"
        );
        let forged = |at: usize, with: u8| {
            let mut forged = record.clone();
            forged[at] = with;
            let checksum = CHECKSUM.checksum(&forged[..end]).to_le_bytes();
            forged[end..].copy_from_slice(&checksum);
            load::<Learner>(&forged).unwrap_err()
        };
        assert_eq!(
            forged(end - 2, 3),
            RecordError::Invalid(Error::InvalidParameter("stalled"))
        );
        assert_eq!(
            forged(end - 1, 15),
            RecordError::Invalid(Error::InvalidParameter("restarts"))
        );
        let radius = 0.375f32.to_le_bytes();
        let at = (0..end).find(|&i| record[i..i + 4] == radius).unwrap() + 37;
        assert_eq!(record[at], 3, "restart_after");
        assert_eq!(
            forged(at, 0),
            RecordError::Invalid(Error::InvalidParameter("restarts"))
        );
        // Below the stall count (2): the count is one `tell` could not have left.
        assert_eq!(
            forged(at, 2),
            RecordError::Invalid(Error::InvalidParameter("stalled"))
        );
    }

    /// An adapter feeding a plant model saves and loads back equal, the model's ticks and
    /// the running episode's previous tick included, and continues identically; the model
    /// is part of its shape.
    #[test]
    fn an_adapter_with_a_model_reloads() {
        use crate::controller::{
            Adapter, AdapterConfig, CorrectedPd, LinearPolicy, Pd, StateFeatures,
        };
        use crate::cost::QuadraticCost;
        type Ctl = CorrectedPd<1, 2, 2, 2, StateFeatures<2>>;
        type Fed = OnlineModel<Affine, 2, 1, 4>;
        type Plain = Adapter<CoordinateSearch<2>, Ctl, QuadraticCost<1>, 2, 2, 1>;
        type Modelled = Adapter<
            CoordinateSearch<2>,
            Ctl,
            QuadraticCost<1>,
            2,
            2,
            1,
            crate::controller::Unguarded,
            Fed,
        >;
        let pd = Pd::<1>::try_new(Vector::repeat(1.0), Vector::repeat(1.5)).unwrap();
        let policy = LinearPolicy::try_new(StateFeatures::identity(), Vector::repeat(1.0)).unwrap();
        let search =
            CoordinateSearch::try_new(bounds(), Vector::zeros(), CoordinateConfig::DEFAULT)
                .unwrap();
        let config = AdapterConfig {
            dt: 0.1,
            failure_cost: 100.0,
            max_faulty_ticks: 0,
            learning_episodes: 10,
        };
        let shaper = QuadraticCost::try_new(Vector::repeat(1.0)).unwrap();
        let plain: Plain = Adapter::try_new(
            search,
            CorrectedPd::new(pd, policy),
            shaper,
            config,
            Vector::zeros(),
        )
        .unwrap();
        let model = OnlineModel::new(RlsModel::try_new(ModelConfig::DEFAULT).unwrap(), Affine);
        let mut a = plain.with_model::<Fed>(model).unwrap();
        assert_ne!(
            <Modelled as Persistent>::SHAPE,
            <Plain as Persistent>::SHAPE
        );
        let mut r = rng(3);
        let plant =
            |x: &Vector<2>, u: &Vector<1>| Vector::<2>::new(x[0] - 0.1 * x[1], x[1] + 0.1 * u[0]);
        let mut x = Vector::<2>::new(1.0, 0.0);
        for _ in 0..2 {
            a.begin_episode(&mut r).unwrap();
            x = Vector::<2>::new(1.0, 0.0);
            for _ in 0..20 {
                let u = a.control(&x, &Vector::repeat(x[0]));
                x = plant(&x, &u);
            }
            a.end_episode().unwrap();
        }
        // Mid-episode: a previous tick is pending in the model.
        a.begin_episode(&mut r).unwrap();
        let u = a.control(&x, &Vector::repeat(x[0]));
        let x = plant(&x, &u);
        let record = bytes(&a);
        let mut loaded: Modelled = load(&record).unwrap();
        assert_eq!(loaded, a);
        assert_eq!(loaded.model().model().ticks(), 2 * 19);
        assert_eq!(
            loaded.control(&x, &Vector::repeat(x[0])),
            a.control(&x, &Vector::repeat(x[0]))
        );
        assert_eq!(loaded, a);
        assert_eq!(loaded.model().model().ticks(), 2 * 19 + 1);
    }

    /// The case found on a narrow box far from zero: LineBO's normalised start rounded past
    /// ±1 and its record was refused on load (`Invalid("origin")`).
    #[test]
    fn line_bo_on_a_narrow_offset_box_reloads() {
        let bounds = Bounds::<1>::try_new([100.0].into(), [100.001].into()).unwrap();
        let s = LineBo::<1, 8>::try_new(bounds, [100.0].into(), LineBoConfig::DEFAULT).unwrap();
        assert_eq!(load::<LineBo<1, 8>>(&bytes(&s)), Ok(s));
        check_reloads(s, 6, true, 1);
    }

    fn sample_record() -> (Vec<u8>, Cmaes<3, 7>) {
        let mut s =
            Cmaes::<3, 7>::try_new(bounds(), Vector::zeros(), CmaesConfig::DEFAULT).unwrap();
        run(&mut s, &mut rng(2), 10);
        (bytes(&s), s)
    }

    /// A record for other sizes or another type is a shape error; another version a version
    /// error (with a valid checksum, so that the header is what is checked).
    #[test]
    fn other_shapes_and_versions_are_refused() {
        let (record, s) = sample_record();
        assert_eq!(load::<Cmaes<3, 7>>(&record), Ok(s));
        assert_eq!(load::<Cmaes<3, 8>>(&record), Err(RecordError::Shape));
        assert_eq!(load::<Cmaes<4, 7>>(&record), Err(RecordError::Shape));
        assert_eq!(load::<Rockstar<3, 7>>(&record), Err(RecordError::Shape));
        assert_eq!(
            load::<(Cmaes<3, 7>, Xoshiro128PlusPlus)>(&record),
            Err(RecordError::Shape)
        );
        let mut other = record.clone();
        let found = FORMAT_VERSION + 1;
        other[0] = u8::try_from(found).unwrap(); // FORMAT_VERSION is a one-byte varint
        let end = other.len() - 4;
        let checksum = CHECKSUM.checksum(&other[..end]).to_le_bytes();
        other[end..].copy_from_slice(&checksum);
        assert_eq!(
            load::<Cmaes<3, 7>>(&other),
            Err(RecordError::Version { found })
        );
        extern crate alloc;
        use alloc::string::ToString;
        assert_eq!(
            RecordError::Version { found: 1 }.to_string(),
            "the record has format version 1, this build reads 8"
        );
    }

    /// Every single corrupted byte, every truncation and every too-small buffer is an error,
    /// never a panic or a wrong state.
    #[test]
    fn corruption_truncation_and_small_buffers_are_errors() {
        let (record, s) = sample_record();
        for i in 0..record.len() {
            for flip in [0x01u8, 0x80, 0xff] {
                let mut bad = record.clone();
                bad[i] ^= flip;
                assert_eq!(
                    load::<Cmaes<3, 7>>(&bad),
                    Err(RecordError::Corrupt),
                    "byte {i}"
                );
            }
        }
        for len in 0..record.len() {
            assert!(load::<Cmaes<3, 7>>(&record[..len]).is_err());
        }
        for len in 0..record.len() {
            let mut buf = std::vec![0u8; len];
            assert_eq!(
                save(&s, &mut buf),
                Err(RecordError::BufferTooSmall),
                "{len}"
            );
        }
        let mut buf = std::vec![0u8; record.len()];
        assert_eq!(save(&s, &mut buf).unwrap(), &record[..]);
    }

    /// Payloads that are not a state of the type, behind a valid checksum and header, are
    /// an encoding error, not a panic.
    #[test]
    fn garbage_behind_a_valid_header_is_refused() {
        let (record, _) = sample_record();
        let mut buf = [0u8; 64];
        let header =
            postcard::to_slice(&(FORMAT_VERSION, Cmaes::<3, 7>::SHAPE.as_slice()), &mut buf)
                .unwrap()
                .to_vec();
        let mut r = rng(5);
        for len in [0usize, 1, 7, 50, record.len() - header.len() - 4, 400] {
            for _ in 0..20 {
                let mut bad = header.clone();
                bad.extend((0..len).map(|_| (r.next_u32() & 0xff) as u8));
                let checksum = CHECKSUM.checksum(&bad).to_le_bytes();
                bad.extend(checksum);
                assert!(load::<Cmaes<3, 7>>(&bad).is_err());
            }
        }
    }

    /// `record` with the `nth` occurrence (from 0) of the four bytes of `find` replaced by
    /// those of `with`, and its checksum made valid again: a forged record.
    fn forge_value(record: &[u8], find: f32, nth: usize, with: f32) -> Vec<u8> {
        let (find, with) = (find.to_le_bytes(), with.to_le_bytes());
        let end = record.len() - 4;
        let at = (0..end - 3)
            .filter(|&i| record[i..i + 4] == find)
            .nth(nth)
            .expect("the value occurs in the record");
        let mut forged = record.to_vec();
        forged[at..at + 4].copy_from_slice(&with);
        let checksum = CHECKSUM.checksum(&forged[..end]).to_le_bytes();
        forged[end..].copy_from_slice(&checksum);
        forged
    }

    /// Checks: a record whose checksum is right but whose content is not is refused with
    /// an error naming the field: a NaN step of the coordinate search (which loaded before
    /// and then asked θ with a NaN coordinate), a NaN in its configuration's initial step,
    /// a box with lower > upper, and a pending candidate outside the box; the record as
    /// saved still loads. The value 0.375 occurs only where the search wrote it: the
    /// configuration's initial step, the steps up and down, the probe's step and the pending
    /// candidate, in that order.
    #[test]
    fn decoded_states_are_validated_naming_the_field() {
        let config = CoordinateConfig {
            initial_step: 0.375,
            ..CoordinateConfig::DEFAULT
        };
        let mut s = CoordinateSearch::<2>::try_new(bounds(), Vector::zeros(), config).unwrap();
        let mut r = rng(3);
        run(&mut s, &mut r, 1);
        let pending = s.ask(&mut r).unwrap();
        assert_eq!(pending, Vector::from([0.375, 0.0]));
        let record = bytes(&s);
        assert_eq!(load::<CoordinateSearch<2>>(&record), Ok(s));
        let refused = |forged: Vec<u8>| load::<CoordinateSearch<2>>(&forged).unwrap_err();
        assert_eq!(
            refused(forge_value(&record, 0.375, 0, f32::NAN)),
            RecordError::Invalid(Error::InvalidParameter("initial_step"))
        );
        assert_eq!(
            refused(forge_value(&record, 0.375, 2, f32::NAN)),
            RecordError::Invalid(Error::NonFinite("steps_up"))
        );
        // The box's first lower bound (−1) raised above its upper bound (1).
        assert_eq!(
            refused(forge_value(&record, -1.0, 0, 2.0)),
            RecordError::Invalid(Error::InvalidBounds { index: 0 })
        );
        // The pending candidate's 0.375 (after the configuration's, the four steps and the
        // probe's) moved out of the box.
        assert_eq!(
            refused(forge_value(&record, 0.375, 6, 1.5)),
            RecordError::Invalid(Error::OutOfBounds("pending"))
        );
        extern crate alloc;
        use alloc::string::ToString;
        assert_eq!(
            RecordError::Invalid(Error::NonFinite("steps_up")).to_string(),
            "the record's payload is not a valid state: steps_up is not finite"
        );
    }
}
