//! Pixel reconstruction filters (stub: box only; replaced by the full set).

use glam::Vec2;
use penumbra_parser::Entity;

pub trait Filter: Send + Sync {
    fn radius(&self) -> Vec2;
    fn evaluate(&self, p: Vec2) -> f32;
}

pub struct BoxFilter {
    pub radius: Vec2,
}

impl Filter for BoxFilter {
    fn radius(&self) -> Vec2 {
        self.radius
    }
    fn evaluate(&self, _p: Vec2) -> f32 {
        1.0
    }
}

#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct FilterError(pub String);

pub fn create_filter(entity: &Entity) -> Result<Box<dyn Filter>, FilterError> {
    let p = &entity.params;
    Ok(Box::new(BoxFilter { radius: Vec2::new(p.get_one_float("xwidth", 0.5), p.get_one_float("ywidth", 0.5)) }))
}
