//! Several artefacts in one scene: each placed instance has its own transform, visibility and
//! shadow flags, and instances of the same asset share its data through an `Arc`.

use std::collections::BTreeMap;
use std::sync::Arc;

use glam::Mat4;

use super::{Aabb, Artefact};
use crate::error::{Error, Result};

/// Identifies an instance in an [`ArtefactSet`]. Never reused after removal, so a stale id fails
/// cleanly instead of moving another object.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ArtefactId(pub u64);

/// One placed artefact.
#[derive(Debug, Clone)]
pub struct Instance {
    /// The shared asset data.
    pub artefact: Arc<Artefact>,
    /// Asset space → world (metres, DESIGN.md conventions). Always finite.
    pub transform: Mat4,
    /// Drawn at all.
    pub visible: bool,
    /// Writes into shadow maps.
    pub casts_shadow: bool,
    /// Darkened by shadows of other objects.
    pub receives_shadow: bool,
}

impl Instance {
    /// Bounds in asset space.
    pub fn local_bounds(&self) -> Aabb {
        self.artefact.bounds
    }

    /// Bounds in world space: the local box's corners transformed.
    pub fn world_bounds(&self) -> Aabb {
        self.artefact.bounds.transformed(&self.transform)
    }
}

/// The artefacts of one scene.
#[derive(Debug, Clone, Default)]
pub struct ArtefactSet {
    instances: BTreeMap<ArtefactId, Instance>,
    next_id: u64,
}

fn check_transform(transform: &Mat4) -> Result<()> {
    if !transform.is_finite() {
        return Err(Error::invalid(format!(
            "artefact transform has a non-finite element: {transform:?}"
        )));
    }
    Ok(())
}

impl ArtefactSet {
    /// An empty set.
    pub fn new() -> Self {
        Self::default()
    }

    /// Places `artefact` with `transform` (visible, casting and receiving shadows). Adding the
    /// same `Arc` again shares its data.
    ///
    /// # Errors
    /// `InvalidArgument` for a non-finite transform.
    pub fn add(&mut self, artefact: Arc<Artefact>, transform: Mat4) -> Result<ArtefactId> {
        check_transform(&transform)?;
        let id = ArtefactId(self.next_id);
        self.next_id += 1;
        self.instances.insert(
            id,
            Instance {
                artefact,
                transform,
                visible: true,
                casts_shadow: true,
                receives_shadow: true,
            },
        );
        Ok(id)
    }

    fn get_mut_or_err(&mut self, id: ArtefactId) -> Result<&mut Instance> {
        self.instances
            .get_mut(&id)
            .ok_or_else(|| Error::invalid(format!("no artefact with id {}", id.0)))
    }

    /// Moves an instance.
    ///
    /// # Errors
    /// `InvalidArgument` for an unknown id or a non-finite transform.
    pub fn set_transform(&mut self, id: ArtefactId, transform: Mat4) -> Result<()> {
        check_transform(&transform)?;
        self.get_mut_or_err(id)?.transform = transform;
        Ok(())
    }

    /// Shows or hides an instance.
    ///
    /// # Errors
    /// `InvalidArgument` for an unknown id.
    pub fn set_visible(&mut self, id: ArtefactId, visible: bool) -> Result<()> {
        self.get_mut_or_err(id)?.visible = visible;
        Ok(())
    }

    /// Sets whether an instance casts and receives shadows.
    ///
    /// # Errors
    /// `InvalidArgument` for an unknown id.
    pub fn set_shadows(&mut self, id: ArtefactId, casts: bool, receives: bool) -> Result<()> {
        let i = self.get_mut_or_err(id)?;
        i.casts_shadow = casts;
        i.receives_shadow = receives;
        Ok(())
    }

    /// Removes an instance and returns it.
    ///
    /// # Errors
    /// `InvalidArgument` for an unknown (or already removed) id.
    pub fn remove(&mut self, id: ArtefactId) -> Result<Instance> {
        self.instances
            .remove(&id)
            .ok_or_else(|| Error::invalid(format!("no artefact with id {}", id.0)))
    }

    /// The instance with `id`, if any.
    pub fn get(&self, id: ArtefactId) -> Option<&Instance> {
        self.instances.get(&id)
    }

    /// Every instance, in the order they were added.
    pub fn iter(&self) -> impl Iterator<Item = (ArtefactId, &Instance)> {
        self.instances.iter().map(|(&id, i)| (id, i))
    }

    /// Number of instances.
    pub fn len(&self) -> usize {
        self.instances.len()
    }

    /// `true` when there are no instances.
    pub fn is_empty(&self) -> bool {
        self.instances.is_empty()
    }

    /// World bounds of every visible instance together, or `None` when none is visible.
    pub fn world_bounds(&self) -> Option<Aabb> {
        self.instances
            .values()
            .filter(|i| i.visible)
            .map(Instance::world_bounds)
            .reduce(|a, b| a.union(&b))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn unit_box() -> Arc<Artefact> {
        Arc::new(Artefact {
            source: "test".into(),
            primitives: Vec::new(),
            materials: Vec::new(),
            textures: Vec::new(),
            extensions_used: Vec::new(),
            extensions_required: Vec::new(),
            warnings: Vec::new(),
            bounds: Aabb {
                min: Vec3::splat(-0.5),
                max: Vec3::splat(0.5),
            },
        })
    }

    #[test]
    fn add_move_remove_and_stale_ids() {
        let mut set = ArtefactSet::new();
        let a = unit_box();
        let id1 = set.add(a.clone(), Mat4::IDENTITY).unwrap();
        let id2 = set
            .add(a.clone(), Mat4::from_translation(Vec3::new(10.0, 0.0, 0.0)))
            .unwrap();
        assert_ne!(id1, id2);
        assert!(Arc::ptr_eq(
            &set.get(id1).unwrap().artefact,
            &set.get(id2).unwrap().artefact
        ));
        let wb = set.get(id2).unwrap().world_bounds();
        assert_eq!(wb.min, Vec3::new(9.5, -0.5, -0.5));
        assert_eq!(wb.max, Vec3::new(10.5, 0.5, 0.5));

        set.set_transform(id1, Mat4::from_scale(Vec3::splat(2.0)))
            .unwrap();
        assert_eq!(set.get(id1).unwrap().world_bounds().max, Vec3::splat(1.0));
        assert_eq!(set.get(id1).unwrap().local_bounds().max, Vec3::splat(0.5));
        let all = set.world_bounds().unwrap();
        assert_eq!(all.min, Vec3::splat(-1.0));
        assert_eq!(all.max, Vec3::new(10.5, 1.0, 1.0));

        set.remove(id1).unwrap();
        assert!(set.remove(id1).is_err());
        assert!(set.set_transform(id1, Mat4::IDENTITY).is_err());
        let id3 = set.add(a, Mat4::IDENTITY).unwrap();
        assert_ne!(id3, id1, "ids are never reused");
        assert_eq!(set.iter().map(|(id, _)| id).collect::<Vec<_>>(), [id2, id3]);
    }

    #[test]
    fn rotated_world_bounds_hold_all_corners() {
        let mut set = ArtefactSet::new();
        let id = set
            .add(
                unit_box(),
                Mat4::from_rotation_y(std::f32::consts::FRAC_PI_4),
            )
            .unwrap();
        let b = set.get(id).unwrap().world_bounds();
        let h = 0.5 * std::f32::consts::SQRT_2;
        assert!((b.max.x - h).abs() < 1e-6 && (b.max.z - h).abs() < 1e-6);
        assert!((b.max.y - 0.5).abs() < 1e-6);
    }

    #[test]
    fn visibility_shadow_flags_and_bad_transforms() {
        let mut set = ArtefactSet::new();
        let id = set.add(unit_box(), Mat4::IDENTITY).unwrap();
        set.set_visible(id, false).unwrap();
        set.set_shadows(id, false, true).unwrap();
        let i = set.get(id).unwrap();
        assert!(!i.visible && !i.casts_shadow && i.receives_shadow);
        assert!(set.world_bounds().is_none());
        let mut bad = Mat4::IDENTITY;
        bad.x_axis.x = f32::NAN;
        assert!(matches!(
            set.set_transform(id, bad),
            Err(Error::InvalidArgument(_))
        ));
        assert!(set
            .add(unit_box(), Mat4::from_scale(Vec3::INFINITY))
            .is_err());
        assert_eq!(set.len(), 1);
    }
}
