//! Choosing the device the network runs on.

use candle_core::Device;

use crate::error::ContactError;

/// Where the network runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DeviceKind {
    /// The CPU (the default; every kernel of this crate has a CPU implementation).
    #[default]
    Cpu,
    /// The first CUDA GPU; needs the crate's `cuda` feature. kNN selection and the EdgeConv
    /// reductions then run as standard tensor operations (a full sort and a gather).
    Cuda,
}

impl std::str::FromStr for DeviceKind {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "cpu" => Ok(Self::Cpu),
            "cuda" => Ok(Self::Cuda),
            other => Err(format!("unknown device '{other}' (cpu or cuda)")),
        }
    }
}

impl std::fmt::Display for DeviceKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Cpu => "cpu",
            Self::Cuda => "cuda",
        })
    }
}

/// Opens the device.
///
/// # Errors
/// [`ContactError::DeviceUnavailable`] for CUDA in a build without the `cuda` feature, or when
/// no GPU can be opened.
pub fn open_device(kind: DeviceKind) -> Result<Device, ContactError> {
    match kind {
        DeviceKind::Cpu => Ok(Device::Cpu),
        DeviceKind::Cuda => open_cuda(),
    }
}

#[cfg(feature = "cuda")]
fn open_cuda() -> Result<Device, ContactError> {
    Device::new_cuda(0).map_err(|e| ContactError::DeviceUnavailable {
        device: "cuda".into(),
        reason: e.to_string().lines().next().unwrap_or_default().to_string(),
    })
}

#[cfg(not(feature = "cuda"))]
fn open_cuda() -> Result<Device, ContactError> {
    Err(ContactError::DeviceUnavailable {
        device: "cuda".into(),
        reason: "this build has no CUDA support; rebuild with `--features cuda`".into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cpu_opens_and_names_parse() {
        assert!(open_device(DeviceKind::Cpu).unwrap().is_cpu());
        assert_eq!("cuda".parse::<DeviceKind>(), Ok(DeviceKind::Cuda));
        let e = "tpu".parse::<DeviceKind>().unwrap_err();
        assert!(e.contains("'tpu'"), "{e}");
    }

    #[cfg(not(feature = "cuda"))]
    #[test]
    fn cuda_without_the_feature_is_a_clear_error() {
        let err = open_device(DeviceKind::Cuda).unwrap_err();
        assert!(matches!(err, ContactError::DeviceUnavailable { .. }));
        assert!(err.to_string().contains("--features cuda"), "{err}");
    }
}
