//! The error type of the `moe-touch` runtime library.

use moe_geom::StageError;
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
    /// The shape stage of a staged estimator failed, and it is not SR-ARAP (whose errors are
    /// `Shape`, inside a pipeline too: [`TouchError::from_estimator`]).
    #[error("shape estimation: {0}")]
    ShapeEstimation(Box<dyn std::error::Error + Send + Sync>),
    /// Contact estimation failed.
    #[error(transparent)]
    #[cfg(feature = "dgcnn")]
    Contact(#[from] moe_contact::ContactError),
    /// The contact stage of a staged estimator failed: its own error, boxed. Errors of this
    /// workspace's estimators do not come this way: the DGCNN's and the KNN baseline's are
    /// [`TouchError::Contact`].
    #[error("contact estimation: {0}")]
    ContactEstimation(Box<dyn std::error::Error + Send + Sync>),
    /// A pipeline's estimator of another crate failed: its own error, boxed (the physics
    /// estimator's is [`TouchError::Physics`]).
    #[error("estimation: {0}")]
    Estimation(Box<dyn std::error::Error + Send + Sync>),
    /// An observation lacks what the pipeline needs.
    #[error("the observation lacks {what}")]
    MissingObservation {
        /// What is missing.
        what: &'static str,
    },
    /// An observation the pipeline cannot take as it is.
    #[error("the observation is refused: {reason}")]
    InvalidObservation {
        /// Why.
        reason: &'static str,
    },
    /// The physics estimator refused its input or failed.
    #[error(transparent)]
    #[cfg(feature = "physics")]
    Physics(#[from] moe_physics::PhysicsError),
    /// A geometric input is malformed.
    #[error(transparent)]
    Geometry(#[from] moe_geom::GeomError),
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
    /// A settings file parsed but holds a value out of range.
    #[error("{}: {source}", path.display())]
    InvalidSettings {
        /// The file.
        path: std::path::PathBuf,
        /// What its settings' own check said.
        source: Box<dyn std::error::Error + Send + Sync>,
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
    /// A pipeline's estimator failed: SR-ARAP's error as [`TouchError::Shape`], the DGCNN's and
    /// the KNN baseline's as [`TouchError::Contact`], the physics estimator's as
    /// [`TouchError::Physics`] — whether they come alone or from a stage of a
    /// [`moe_geom::Staged`] estimator — and any other estimator's boxed, by stage
    /// ([`TouchError::ShapeEstimation`], [`TouchError::ContactEstimation`]) or whole
    /// ([`TouchError::Estimation`]).
    pub fn from_estimator<E: std::error::Error + Send + Sync + 'static>(e: E) -> Self {
        let boxed: Box<dyn std::error::Error + Send + Sync> = Box::new(e);
        match boxed.downcast::<StageError>() {
            Ok(staged) => match *staged {
                StageError::Shape(e) => Self::from_boxed(e, Self::ShapeEstimation),
                StageError::Contact(e) => Self::from_boxed(e, Self::ContactEstimation),
            },
            Err(e) => Self::from_boxed(e, Self::Estimation),
        }
    }

    /// The variant of this workspace's own error types; `other` boxes an estimator's error of
    /// another type.
    fn from_boxed(
        boxed: Box<dyn std::error::Error + Send + Sync>,
        other: fn(Box<dyn std::error::Error + Send + Sync>) -> Self,
    ) -> Self {
        let boxed = match boxed.downcast::<moe_arap::ArapError>() {
            Ok(e) => return Self::Shape(*e),
            Err(b) => b,
        };
        #[cfg(feature = "dgcnn")]
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
    /// directly (`?`) or through a pipeline's staged estimator; another estimator's error is
    /// boxed, by stage or whole.
    #[test]
    #[cfg(feature = "dgcnn")]
    fn an_estimator_error_takes_one_path() {
        let arap = || moe_arap::ArapError::InvalidConfig {
            name: "alpha",
            value: -1.0,
            reason: "must be non-negative",
        };
        let direct: TouchError = arap().into();
        for staged in [
            TouchError::from_estimator(arap()),
            TouchError::from_estimator(StageError::Shape(Box::new(arap()))),
        ] {
            assert!(matches!(staged, TouchError::Shape(_)), "{staged:?}");
            assert_eq!(staged.to_string(), direct.to_string());
        }
        let net = TouchError::from_estimator(StageError::Contact(Box::new(
            moe_contact::ContactError::InvalidBatch {
                message: "empty".into(),
            },
        )));
        assert!(matches!(net, TouchError::Contact(_)), "{net:?}");
        let custom = || std::io::Error::other("a custom estimator");
        let shape = TouchError::from_estimator(StageError::Shape(Box::new(custom())));
        assert!(matches!(shape, TouchError::ShapeEstimation(_)), "{shape:?}");
        assert_eq!(shape.to_string(), "shape estimation: a custom estimator");
        let contact = TouchError::from_estimator(StageError::Contact(Box::new(custom())));
        assert!(
            matches!(contact, TouchError::ContactEstimation(_)),
            "{contact:?}"
        );
        let whole = TouchError::from_estimator(custom());
        assert!(matches!(whole, TouchError::Estimation(_)), "{whole:?}");
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
