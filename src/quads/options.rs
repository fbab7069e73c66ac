//! Options of the quads stage.

use serde::{Deserialize, Serialize};

use super::error::QuadsError;

/// Options of the quads stage.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct QuadsOptions {
    /// Target edge length of the quads, model units. Default (`null`): the
    /// input's mean edge length (or `size_relative` when given).
    pub size: Option<f64>,
    /// Target edge length as a fraction of the bounding-box diagonal, used
    /// when `size` is not given. Default `null`.
    pub size_relative: Option<f64>,
    /// Element order: 1 (4-node quadrangles) or 2 (9-node quadrangles whose
    /// new nodes lie on the input surface). Default 1.
    pub order: u8,
    /// Smoothing sweeps over the vertices (0 = none). Default 10.
    pub smoothing_iterations: usize,
}

impl Default for QuadsOptions {
    fn default() -> Self {
        Self { size: None, size_relative: None, order: 1, smoothing_iterations: 10 }
    }
}

impl QuadsOptions {
    /// Checks ranges.
    ///
    /// # Errors
    /// [`QuadsError::InvalidOption`] naming the field.
    pub fn validate(&self) -> Result<(), QuadsError> {
        let positive = |name: &'static str, v: Option<f64>| match v {
            Some(x) if !(x > 0.0 && x.is_finite()) => {
                Err(QuadsError::InvalidOption { name, reason: format!("must be a positive finite number, got {x}") })
            }
            _ => Ok(()),
        };
        positive("size", self.size)?;
        positive("size_relative", self.size_relative)?;
        if let Some(r) = self.size_relative
            && r > 1.0
        {
            return Err(QuadsError::InvalidOption {
                name: "size_relative",
                reason: format!("must be at most 1 (a fraction of the bounding-box diagonal), got {r}"),
            });
        }
        if !matches!(self.order, 1 | 2) {
            return Err(QuadsError::InvalidOption {
                name: "order",
                reason: format!("must be 1 or 2, got {}", self.order),
            });
        }
        if self.smoothing_iterations > 1000 {
            return Err(QuadsError::InvalidOption {
                name: "smoothing_iterations",
                reason: format!("must be at most 1000, got {}", self.smoothing_iterations),
            });
        }
        Ok(())
    }

    /// The target edge length for a surface of mean edge length
    /// `mean_edge` and bounding-box diagonal `diagonal`.
    pub fn target_size(&self, mean_edge: f64, diagonal: f64) -> f64 {
        match (self.size, self.size_relative) {
            (Some(h), _) => h,
            (None, Some(r)) => r * diagonal,
            (None, None) => mean_edge,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_validate_and_bad_values_name_the_field() {
        assert!(QuadsOptions::default().validate().is_ok());
        let bad = |o: QuadsOptions| match o.validate() {
            Err(QuadsError::InvalidOption { name, .. }) => name,
            other => panic!("expected InvalidOption, got {other:?}"),
        };
        assert_eq!(bad(QuadsOptions { size: Some(0.0), ..Default::default() }), "size");
        assert_eq!(bad(QuadsOptions { size: Some(f64::NAN), ..Default::default() }), "size");
        assert_eq!(bad(QuadsOptions { size_relative: Some(2.0), ..Default::default() }), "size_relative");
        assert_eq!(bad(QuadsOptions { order: 3, ..Default::default() }), "order");
        assert_eq!(bad(QuadsOptions { smoothing_iterations: 5000, ..Default::default() }), "smoothing_iterations");
    }

    #[test]
    fn size_precedence_is_size_then_relative_then_mean_edge() {
        let o = QuadsOptions::default();
        assert_eq!(o.target_size(0.1, 10.0), 0.1);
        let o = QuadsOptions { size_relative: Some(0.05), ..Default::default() };
        assert_eq!(o.target_size(0.1, 10.0), 0.5);
        let o = QuadsOptions { size: Some(0.2), size_relative: Some(0.05), ..Default::default() };
        assert_eq!(o.target_size(0.1, 10.0), 0.2);
    }

    #[test]
    fn unknown_fields_are_rejected() {
        assert!(serde_json::from_str::<QuadsOptions>(r#"{"sise": 1}"#).is_err());
    }
}
