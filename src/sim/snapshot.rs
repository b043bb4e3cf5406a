use super::Emission;
use glam::Vec3;

/// What a surface is, for the renderer's choice of material (and, later, assessment): the
/// procedure says it; the renderer knows no organ.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SurfaceRole {
    /// Organ tissue (parenchyma, wall, muscle).
    #[default]
    Tissue,
    /// What the task is about (a mass to remove, a specimen): highlighted once found.
    Target,
    Artery,
    Vein,
    /// A duct or ureter.
    Duct,
    Fat,
    /// A membrane, fascia or peritoneum.
    Membrane,
    /// The cavity's lining: the body wall under its peritoneum (the operative field).
    Wall,
    /// A hollow organ's outer surface (serosa) seen beside the task (the operative field).
    Viscus,
    /// A thin-walled sac whose dark green-grey contents show through its wall.
    Sac,
}

/// What a renderer needs of one model at one instant.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ModelSnapshot {
    pub name: String,
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub indices: Vec<u32>,
    /// Region index per triangle.
    pub regions: Vec<u8>,
    /// The role of each region (index = region); a region past the end is tissue.
    pub roles: Vec<SurfaceRole>,
    /// Per vertex: whether it lies on the edge of a cut (drawn as cut tissue).
    pub cut_edge: Vec<bool>,
    /// Per vertex: seared by an energy instrument (drawn charred); empty: none is.
    pub seared: Vec<bool>,
}

#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ToolSnapshot {
    pub tip: Vec3,
    pub direction: Vec3,
    /// Laser hit point, if the beam hits tissue.
    pub beam_end: Option<Vec3>,
    /// Where a beam that hits nothing ends (its range), for drawing; none when it hits (see
    /// `beam_end`) or the instrument has no beam.
    pub beam_reach: Option<Vec3>,
    pub active: bool,
    /// Which instrument the hand holds: 0 its own (`ProcedureInfo::tools`), `k` the
    /// procedure's `swap[k - 1]`.
    pub instrument: u8,
    /// What the instrument looks like, and how far its jaws are open (0 shut, 1 wide).
    pub shape: InstrumentShape,
    pub jaw: f32,
    /// The instrument's roll about its shaft: its local +Y (the plane its jaws open in, the
    /// way an L-hook's foot points); zero when it has none.
    pub up: Vec3,
}

/// The working end of a laparoscopic instrument, as drawn: each on a 5 mm shaft.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum InstrumentShape {
    /// A shaft and two short prongs (an instrument the procedure does not name).
    #[default]
    Plain,
    /// Two jaws hinged at the shaft's end, opening up to 30 degrees each.
    Grasper,
    /// Two curved blades, opening up to 20 degrees each.
    Scissors,
    /// Two straight jaws that close a clip, opening up to 12 degrees each.
    ClipApplier,
    /// An electrosurgical L-hook: an insulated neck and a short foot at right angles.
    Hook,
    /// A laser fibre's probe: the shaft tapers to the fibre.
    Laser,
    /// A blunt probe with a rounded end.
    Probe,
}

/// An immutable picture of the simulation, published for renderer and haptic threads.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Snapshot {
    pub step: u64,
    pub time_s: f64,
    pub models: Vec<ModelSnapshot>,
    pub tools: [ToolSnapshot; 2],
    /// Reaction force on each tool, newtons.
    pub reactions: [Vec3; 2],
    /// The trainee has found the target (the renderer highlights surfaces whose role is
    /// [`SurfaceRole::Target`]).
    pub target_found: bool,
    /// Recent emissions (smoke where an energized instrument cut), oldest first: a bounded
    /// few (the procedure keeps about the last 2 s), which the renderer animates from
    /// `time_s`. Empty for procedures that give off nothing.
    pub emissions: Vec<Emission>,
    /// Bleeding sources, for the renderer's blood (pools that grow while they bleed, drops);
    /// empty where nothing bleeds.
    pub bleeding: Vec<super::Bleed>,
    /// Where the procedure's laparoscope looks from, once the trainee has moved it with a
    /// device (`ProcedureInfo::scope_hand`); `None`: the procedure's own viewpoint. The
    /// desktop window and headless frames show the field from here.
    pub scope: Option<ScopeView>,
    /// A picture the procedure's imaging shows, where it has one (an interventional
    /// fluoroscope: the last frame held, the roadmap over it when on); headless frames write
    /// it beside the eyes' as `fluoro_NNNN.png`. None for the others.
    pub picture: Option<std::sync::Arc<crate::imaging::fluoro::Picture>>,
}

/// A laparoscope's place: its eye and the point it looks at, metres (field frame, y up).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScopeView {
    pub eye: Vec3,
    pub target: Vec3,
}
