//! The flat, fully resolved scene description the interpreter produces.

use crate::diag::FileLoc;
use crate::params::ParamSet;
use crate::transform::{AnimatedTransform, Transform};
use std::path::PathBuf;

/// A directive's type name (`"sphere"`, `"matte"`, `"halton"`…), its parameters and where it was written.
#[derive(Clone, Debug, PartialEq)]
pub struct Entity {
    pub kind: String,
    pub params: ParamSet,
    pub loc: FileLoc,
}

impl Entity {
    pub fn new(kind: impl Into<String>, params: ParamSet, loc: FileLoc) -> Self {
        Entity { kind: kind.into(), params, loc }
    }
    /// An entity with pbrt-v3's default type, as if written with no parameters.
    pub fn default_of(kind: &str) -> Self {
        Entity { kind: kind.to_string(), params: ParamSet::new(), loc: FileLoc::builtin() }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct CameraDesc {
    pub entity: Entity,
    /// The CTM when `Camera` was given.
    pub camera_from_world: AnimatedTransform,
    /// Its inverse.
    pub world_from_camera: AnimatedTransform,
    /// `MediumInterface` outside medium in effect at `Camera`, if any.
    pub medium: Option<String>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct ShapeDesc {
    pub entity: Entity,
    /// World from object (penumbra renders in world space).
    pub render_from_object: AnimatedTransform,
    pub reverse_orientation: bool,
    /// Index into `SceneDescription::materials`; `None` for `Material "none"`/`""` (interface only).
    pub material: Option<usize>,
    /// Index into `SceneDescription::area_lights` when an `AreaLightSource` was in effect.
    pub area_light: Option<usize>,
    pub inside_medium: Option<String>,
    pub outside_medium: Option<String>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct LightDesc {
    pub entity: Entity,
    pub render_from_light: AnimatedTransform,
    pub medium: Option<String>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct MaterialDesc {
    /// `kind` is the material type (`"matte"`…); for `MakeNamedMaterial` it is the `"string type"` value.
    pub entity: Entity,
    /// The name given to `MakeNamedMaterial`, if any.
    pub name: Option<String>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TextureKind {
    Float,
    /// pbrt-v3's `"spectrum"` (alias `"color"`).
    Spectrum,
}

#[derive(Clone, Debug, PartialEq)]
pub struct TextureDesc {
    pub name: String,
    pub kind: TextureKind,
    /// `kind` is the texture class (`"imagemap"`, `"checkerboard"`…).
    pub entity: Entity,
    pub render_from_texture: AnimatedTransform,
}

#[derive(Clone, Debug, PartialEq)]
pub struct MediumDesc {
    pub name: String,
    pub entity: Entity,
    pub render_from_medium: AnimatedTransform,
}

/// `ObjectBegin "name"` … `ObjectEnd`.
#[derive(Clone, Debug, PartialEq)]
pub struct InstanceDefinition {
    pub name: String,
    pub shapes: Vec<ShapeDesc>,
    pub loc: FileLoc,
}

/// `ObjectInstance "name"`.
#[derive(Clone, Debug, PartialEq)]
pub struct InstanceUse {
    /// Index into `SceneDescription::instance_definitions`.
    pub definition: usize,
    /// World from instance: the CTM at `ObjectInstance`.
    pub render_from_instance: AnimatedTransform,
    pub loc: FileLoc,
}

#[derive(Clone, Debug, PartialEq)]
pub struct SceneDescription {
    pub camera: CameraDesc,
    pub film: Entity,
    pub sampler: Entity,
    pub filter: Entity,
    pub integrator: Entity,
    pub accelerator: Entity,
    /// `TransformTimes` (default 0, 1).
    pub transform_times: (f32, f32),
    pub shapes: Vec<ShapeDesc>,
    pub lights: Vec<LightDesc>,
    /// One entity per `AreaLightSource` directive; shapes refer to them by index.
    pub area_lights: Vec<Entity>,
    /// Every material (anonymous `Material`s and `MakeNamedMaterial`s); shapes refer to them by index.
    pub materials: Vec<MaterialDesc>,
    /// Every texture definition, in order; later definitions of a name shadow earlier ones.
    pub textures: Vec<TextureDesc>,
    pub media: Vec<MediumDesc>,
    pub instance_definitions: Vec<InstanceDefinition>,
    pub instances: Vec<InstanceUse>,
    /// The top-level scene file (or `None` for in-memory text) and the directory
    /// that relative asset paths (`filename`, `mapname`) resolve against.
    pub main_file: Option<PathBuf>,
    pub base_dir: PathBuf,
    /// Every file read while parsing (the main file, its `Include`s, `.spd` files), for hashing and reports.
    pub files_read: Vec<PathBuf>,
}

/// pbrt-v3's parameters whose value names a file to read (`plymesh`'s `filename`, `imagemap`'s
/// `filename`, an infinite, goniometric or projection light's `mapname`, `fourier`'s
/// `bsdffile`, `realistic`'s `lensfile`).
pub const ASSET_PARAMS: [&str; 4] = ["filename", "mapname", "bsdffile", "lensfile"];

impl SceneDescription {
    /// Resolves an asset file name the way pbrt-v3 does: absolute paths as they are,
    /// relative ones against the directory of the top-level scene file.
    pub fn resolve_path(&self, name: &str) -> PathBuf {
        let p = PathBuf::from(name);
        if p.is_absolute() {
            p
        } else {
            self.base_dir.join(p)
        }
    }

    /// The asset files the scene's entities name (pbrt-v3's file-valued parameters
    /// [`ASSET_PARAMS`]: PLY meshes, image textures and environment maps, measured BSDFs, lens
    /// files), resolved as [`resolve_path`](Self::resolve_path) resolves them, each once, in
    /// the order of the description. Whether they exist is not checked. Reading the parameters
    /// does not mark them used.
    pub fn asset_files(&self) -> Vec<PathBuf> {
        let entities = std::iter::once(&self.camera.entity)
            .chain(self.shapes.iter().map(|s| &s.entity))
            .chain(self.instance_definitions.iter().flat_map(|d| d.shapes.iter().map(|s| &s.entity)))
            .chain(self.lights.iter().map(|l| &l.entity))
            .chain(&self.area_lights)
            .chain(self.materials.iter().map(|m| &m.entity))
            .chain(self.textures.iter().map(|t| &t.entity))
            .chain(self.media.iter().map(|m| &m.entity));
        let mut out: Vec<PathBuf> = Vec::new();
        for e in entities {
            for name in ASSET_PARAMS {
                let Some(p) = e.params.find(name) else { continue };
                let crate::ParamValue::String(v) = &p.value else { continue };
                for f in v {
                    let path = self.resolve_path(f);
                    if !out.contains(&path) {
                        out.push(path);
                    }
                }
            }
        }
        out
    }

    /// Moves the whole scene by `world_from_world` (applied after every transform of the
    /// description): shapes, instances, lights, textures, media and the camera together, so
    /// the image is unchanged up to rounding when `world_from_world` is a rigid motion. (Under
    /// a scale by `s`, point-like lights' irradiance changes by 1/s²: pbrt's intensities are
    /// per steradian, not per area. Callers that want the same image scale them.)
    pub fn transform_world(&mut self, world_from_world: &Transform) {
        let apply = |t: &mut AnimatedTransform| {
            t.start = world_from_world.compose(&t.start);
            t.end = world_from_world.compose(&t.end);
        };
        apply(&mut self.camera.world_from_camera);
        let inv = world_from_world.inverse();
        let c = &mut self.camera.camera_from_world;
        c.start = c.start.compose(&inv);
        c.end = c.end.compose(&inv);
        self.shapes.iter_mut().for_each(|s| apply(&mut s.render_from_object));
        // Instance definitions' shapes are in instance space: only their uses move.
        self.instances.iter_mut().for_each(|i| apply(&mut i.render_from_instance));
        self.lights.iter_mut().for_each(|l| apply(&mut l.render_from_light));
        self.textures.iter_mut().for_each(|t| apply(&mut t.render_from_texture));
        self.media.iter_mut().for_each(|m| apply(&mut m.render_from_medium));
    }
}
