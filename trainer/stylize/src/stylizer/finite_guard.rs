//! Refuses stylizer output that contains NaN or Inf (or has the wrong size), naming the
//! stylizer and the view size, so one broken model cannot poison training views silently.

use anyhow::{bail, Result};

use super::{Image, Stylizer};

pub struct FiniteGuard {
    inner: Box<dyn Stylizer>,
}

impl FiniteGuard {
    pub fn new(inner: Box<dyn Stylizer>) -> FiniteGuard {
        FiniteGuard { inner }
    }
}

impl Stylizer for FiniteGuard {
    fn name(&self) -> String {
        self.inner.name()
    }

    fn stylize(&self, content: &Image) -> Result<Image> {
        let out = self.inner.stylize(content)?;
        let size = content.size_text();
        if (out.width, out.height) != (content.width, content.height) || out.data.len() != out.width * out.height * 3 {
            bail!("stylizer {} returned a {} image for a {size} view", self.name(), out.size_text());
        }
        if let Some(bad) = out.data.iter().find(|v| !v.is_finite()) {
            let what = if bad.is_nan() { "NaN" } else { "Inf" };
            bail!("stylizer {} returned {what} for a {size} view", self.name());
        }
        Ok(out)
    }
}
