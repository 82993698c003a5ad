//! The error type of the `moe-touch` runtime library.

use moe_io::IoError;

/// Everything that can go wrong in the pipeline library.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TouchError {
    /// Reading or writing a file failed (the error names the file).
    #[error(transparent)]
    Io(#[from] IoError),
    /// Shape estimation failed.
    #[error(transparent)]
    Shape(#[from] moe_arap::ArapError),
    /// A contact model has no card beside its weights.
    #[error("{}: no model card beside the weights (the card carries the input features, their normalisation and the threshold)", path.display())]
    MissingModelCard {
        /// Where the card was looked for.
        path: std::path::PathBuf,
    },
    /// A shape estimator that is neither SR-ARAP nor the physics estimator failed (their
    /// errors are `Shape` and `Physics`, inside a pipeline too: `from_shape_stage`).
    #[error("shape estimation: {0}")]
    ShapeEstimation(Box<dyn std::error::Error + Send + Sync>),
    /// Contact estimation failed.
    #[error(transparent)]
    Contact(#[from] moe_contact::ContactError),
    /// The contact estimator of a pipeline failed: its own error, boxed. Errors of this
    /// workspace's estimators do not come this way: the DGCNN's and the KNN baseline's are
    /// [`TouchError::Contact`], the physics estimator's [`TouchError::Physics`].
    #[error("contact estimation: {0}")]
    ContactEstimation(Box<dyn std::error::Error + Send + Sync>),
    /// The physics estimator refused its input or failed.
    #[error(transparent)]
    #[cfg(feature = "physics")]
    Physics(#[from] moe_physics::PhysicsError),
    /// A geometric input is malformed.
    #[error(transparent)]
    Geometry(#[from] moe_geom::GeomError),
    /// Surface reconstruction failed.
    #[error(transparent)]
    Surface(#[from] moe_gpis::GpisError),
    /// An image does not have the size the camera intrinsics give.
    #[error("{what}: expected {expected}, got {got}")]
    ImageSize {
        /// Which image and unit.
        what: &'static str,
        /// Size from the intrinsics.
        expected: usize,
        /// Size given.
        got: usize,
    },
    /// A parameter of the pipeline (contact threshold, temporal filter) is out of range.
    #[error("{name} = {value}: {reason}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What is wrong.
        reason: &'static str,
    },
    /// A marker-detector parameter is out of range.
    #[error("marker detector: {name} = {value}: {reason}")]
    InvalidDetector {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What is wrong.
        reason: &'static str,
    },
    /// A frame of a stream is not after the previous one (out of order, or a repeated time).
    #[error(
        "frame time {time_secs} s is not after the previous frame's {previous_secs} s: a stream's \
         frames must arrive in time order without repeats (reset the pipeline to start another)"
    )]
    StreamOutOfOrder {
        /// The previous frame's time, seconds.
        previous_secs: f64,
        /// This frame's time, seconds.
        time_secs: f64,
    },
}

impl TouchError {
    /// A pipeline's shape stage failed: SR-ARAP's error as [`TouchError::Shape`], the physics
    /// estimator's as [`TouchError::Physics`], any other estimator's boxed
    /// ([`TouchError::ShapeEstimation`]) — one path per failure whatever the stage's type.
    pub fn from_shape_stage<E: std::error::Error + Send + Sync + 'static>(e: E) -> Self {
        Self::from_stage(e, Self::ShapeEstimation)
    }

    /// A pipeline's contact stage failed: the DGCNN's and the KNN baseline's error as
    /// [`TouchError::Contact`], the physics estimator's as [`TouchError::Physics`], any other
    /// estimator's boxed ([`TouchError::ContactEstimation`]).
    pub fn from_contact_stage<E: std::error::Error + Send + Sync + 'static>(e: E) -> Self {
        Self::from_stage(e, Self::ContactEstimation)
    }

    /// The variant of this workspace's own error types, whichever stage raised them; `other`
    /// boxes an estimator's error of another type.
    fn from_stage<E: std::error::Error + Send + Sync + 'static>(
        e: E,
        other: fn(Box<dyn std::error::Error + Send + Sync>) -> Self,
    ) -> Self {
        let boxed: Box<dyn std::error::Error + Send + Sync> = Box::new(e);
        let boxed = match boxed.downcast::<moe_arap::ArapError>() {
            Ok(e) => return Self::Shape(*e),
            Err(b) => b,
        };
        let boxed = match boxed.downcast::<moe_contact::ContactError>() {
            Ok(e) => return Self::Contact(*e),
            Err(b) => b,
        };
        #[cfg(feature = "physics")]
        let boxed = match boxed.downcast::<moe_physics::PhysicsError>() {
            Ok(e) => return Self::Physics(*e),
            Err(b) => b,
        };
        other(boxed)
    }
}

/// Formats an error and its causes on one line (`outer: inner: root`), without backtraces: a
/// cause whose text the previous message already includes is left out, so an error that names
/// its source in its own message is not printed twice. Both command-line tools print errors
/// this way.
pub fn one_line(err: &(dyn std::error::Error + 'static)) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut cause = Some(err);
    while let Some(e) = cause {
        let s = e.to_string();
        if parts.last().is_none_or(|prev| !prev.contains(&s)) {
            parts.push(s.lines().next().unwrap_or_default().to_owned());
        }
        cause = e.source();
    }
    parts.join(": ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("reading frame 3: {0}")]
    struct Outer(#[source] TouchError);

    /// An SR-ARAP failure reaches the caller as `Shape` whether it came from the estimator
    /// directly (`?`) or through a pipeline's shape stage; another estimator's error is boxed.
    #[test]
    fn a_stage_error_takes_one_path() {
        let arap = || moe_arap::ArapError::InvalidConfig {
            name: "alpha",
            value: -1.0,
            reason: "must be non-negative",
        };
        let direct: TouchError = arap().into();
        let staged = TouchError::from_shape_stage(arap());
        assert!(matches!(staged, TouchError::Shape(_)), "{staged:?}");
        assert_eq!(staged.to_string(), direct.to_string());
        let net = TouchError::from_contact_stage(moe_contact::ContactError::InvalidBatch {
            message: "empty".into(),
        });
        assert!(matches!(net, TouchError::Contact(_)), "{net:?}");
        let other = TouchError::from_shape_stage(std::io::Error::other("a custom estimator"));
        assert!(matches!(other, TouchError::ShapeEstimation(_)), "{other:?}");
    }

    #[test]
    fn one_line_names_each_cause_once() {
        let inner = TouchError::InvalidParameter {
            name: "contact threshold",
            value: 2.0,
            reason: "must be in [0, 1]",
        };
        // The outer message already includes the inner one: it is not repeated.
        let line = one_line(&Outer(inner));
        assert_eq!(
            line,
            "reading frame 3: contact threshold = 2: must be in [0, 1]"
        );
        assert_eq!(line.matches("threshold").count(), 1, "{line}");
    }
}
