#pragma once

#include <string>

#include "perception/direct_alignment.h"
#include "perception/floor_features.h"
#include "perception/geometry/options.h"
#include "perception/ground_motion.h"
#include "perception/height_filter.h"
#include "perception/motion_evidence.h"
#include "perception/moving_objects.h"
#include "perception/zero_disparity.h"

namespace monoplane {

// How samples become floor, obstacle, drop-off, moving or unknown (the paper's steps 4-5).
struct ClassificationOptions {
  // Sample spacing on the finest search level, pixels. Labels are per sample, upsampled.
  int sample_stride = 2;
  // Heights (metres): at or above obstacle_min_height_m an obstacle, at or below
  // -drop_off_min_depth_m a drop-off.
  double obstacle_min_height_m = 0.03;
  double drop_off_min_depth_m = 0.03;
  // Smallest error assumed for a zero disparity, input pixels; each sample's own error
  // (ZeroDisparityField::sigma_px) is used when larger. A point is only called floor when its
  // error keeps its height within the thresholds above; otherwise unknown.
  double disparity_sigma_px = 0.05;
  // An obstacle or drop-off needs a zero disparity of at least this many sigmas.
  double min_disparity_sigmas = 3.0;
  // Floor needs |height| + this many height sigmas below obstacle_min_height_m: a point that
  // could be an obstacle within its error is unknown, not floor.
  double floor_max_height_sigmas = 3.0;
  // An obstacle or drop-off needs the floor hypothesis (zero disparity) to misfit the sample's own
  // 3x3 neighbourhood by at least this many grey levels (mean |difference|) more than its zero
  // disparity does. Otherwise the neighbourhood cannot tell them apart (the matching window
  // carried an obstacle's parallax onto the floor next to it, or there is no texture): unknown.
  bool check_floor_hypothesis = true;
  double min_floor_misfit = 0.0;
  // Where a sample's window has at least this much texture (grey levels^2 per pixel^2; 0 = off),
  // the floor must misfit every 3x3 neighbourhood around it, its own and its 8 neighbours': a
  // strong edge in the window, most often the occluding contour of a thing in front, gives the
  // window that thing's parallax, and a sample up to half a window beside the contour on the floor
  // takes it too. One of the shifted neighbourhoods lies on the floor alone there. On a weakly
  // textured surface the floor fits a shifted neighbourhood about as well as the surface does, so
  // the rule would cost it its measurements; the rule holds only where texture is strong.
  double contour_min_texture = 30.0;
  // Minimum texture along the epipolar line (mean squared gradient, grey levels^2 per pixel^2, >
  // 0); below it a pixel is unknown, never floor. Above it the sample's error (from its texture,
  // its residual and the step the search still asked for) decides its label: weakly textured
  // faces (dark posts, plain walls) are measured, to the precision they allow.
  double min_texture = 0.25;
  // A sample is floor by its own measurement only with at least this much texture (grey levels^2
  // per pixel^2): below it, down to min_texture, significant parallax shows that something stands
  // there, but no parallax is no evidence of floor. (The column fill still labels a short gap
  // between two floor samples floor whatever its texture: nothing 3 cm high hides in it.) The
  // coarse levels' windows give a weakly textured face the zero parallax of its base on the floor,
  // and the finest level's damped steps hardly move it (the lowest centimetres of a plain box read
  // floor); and weakly textured floor is where a thing the camera sees only in part hides (the
  // floor under a table top above the view reads free).
  double floor_min_texture = 1.0;
  // ... or, for a measured sample the rules leave unknown, with at least this much texture across
  // the epipolar line (grey levels^2 per pixel^2; 0 = off). A floor whose grain or seams run
  // along the lines of forward motion (floorboards laid along the way, radial from the focus of
  // expansion like the lines) has little texture along them, which its height sigma says, but is
  // textured; a faint floor with little texture in any direction is not floor by this.
  double floor_min_texture_across = 4.0;
  // That floor votes free in the local map only where it lies farther than this from every
  // measured obstacle point of the pair (m; 0 = in the image's labels only; the free rays between
  // two such samples of a column may pass a little nearer). Near what stands on the floor the
  // camera may see the floor under something it does not see: a table top above the view over
  // its legs.
  double floor_across_free_clearance_m = 0.6;
  // Top view: a thin post that stands on the floor and reaches the top of the view (a table's
  // leg: its placed points one connected group of cells at most support_max_width_m across, from
  // within support_max_base_m of the floor up to the top support_top_samples sample rows) may
  // carry something above the view (a table top, which the default mount sees only from more
  // than 3.5 m away). Floor within this of such a post votes no free in the local map: a robot
  // taller than the top would hit it there (m; 0 = off).
  double support_free_clearance_m = 1.0;
  double support_max_width_m = 0.3;  // > 0
  double support_max_base_m = 0.15;  // >= 0
  int support_top_samples = 4;       // >= 1
  // SequenceDetector: a post keeps the floor near it from reading free for this many detected
  // frames after it was last found (a frame may miss a leg the frames before it found; 0: only
  // the frame that finds it).
  int support_memory_frames = 4;
  // Maximum mean |difference| after alignment, grey levels; above it unknown (or moving).
  double max_residual = 12.0;
  // Dense test: an offset perpendicular to the epipolar line of at least this many input pixels
  // (and min_disparity_sigmas) marks motion of its own (0 = off). Off by default: on tiled
  // and grained floors the aperture problem makes it call parts of the floor moving, and things
  // that move move farther than the dense search follows; the tracked-corner test below finds them.
  double moving_min_perpendicular_px = 0.0;
  // Tracked corners: a corner shared by the pair that lies farther than this from its epipolar
  // line under the fitted motion cannot be a static point (input pixels). Where two such
  // corners lie within moving_track_radius_px of each other, the samples within that radius that
  // are not floor are labelled moving (>= 0; 0 turns the track test off). Off by default: the
  // dense motion evidence (DetectorOptions::motion_evidence) finds moving things per pixel, and a
  // disc around a corner also takes the static obstacles next to a moving one.
  double moving_track_min_px = 4.0;
  double moving_track_radius_px = 0.0;
  // Pixels carried along the flow from earlier frames' moving regions
  // (MotionEvidenceOptions::carry_frames) label an obstacle sample moving only when its height
  // estimate holds at most this many measurements: a thing that moves puts a new point under the
  // sample every frame, while a static one behind a passing thing (onto which the flow at the
  // thing's border spreads) is measured at one height pair after pair. Samples without a label
  // take it always, floor samples never.
  int moving_carried_max_measurements = 2;
  // The moving mask is taken per superpixel (with Aggregation::kSegments): a segment whose
  // samples it covers at least this fraction of moves whole (its samples without a label), one it
  // covers less loses them. The flow's regions follow the image's edges only to a few pixels;
  // the segments follow them better. 0 = off.
  double moving_segment_fraction = 0.5;
  // Points farther than this from the robot (metres) are unknown: not reliable.
  double max_range_m = 6.0;
  // An obstacle or drop-off point goes into the top view (local map, obstacle points) only when
  // its footprint is known to within 0.05 m + this fraction of its range (one sigma of the zero
  // disparity moves it along its ray). Far, tall points whose rays graze their height are
  // labelled in the image but not placed, rather than smeared far beyond where they are.
  double max_footprint_sigma_ratio = 0.03;
  // ... and when it lies on a surface: at least min_surface_neighbours of its 8 neighbouring
  // samples (measured, any label) are at ranges from the camera that a surface seen at
  // min_surface_angle_deg or more to the viewing ray would give. A sample whose matching window
  // straddles a depth edge measures a mix of the two depths ("veil" points, as a lidar's mixed
  // returns); without this they smear an obstacle's edge along its rays in the top view.
  // Angle in degrees, 0 = off.
  double min_surface_angle_deg = 10.0;
  int min_surface_neighbours = 3;
  // Where the floor ends in an image column (the samples above it are not floor), the floor
  // samples whose matching window reaches the edge (half a window) straddle it: the floor label
  // climbs onto the lowest pixels of what stands there (a wall seen at a grazing angle, a box
  // without texture), detected or not, and their cells hold its base. Below floor_edge_samples
  // samples that are not floor, those cells are not free in the local map; below fewer (a seam, a
  // textureless spot in the floor) they just give no free vote. 0 = off.
  int floor_edge_samples = 3;
  // ... and in the image's labels those floor samples are unknown: the label says what the map
  // does. The floor label otherwise climbs onto the base of a plain wall or box, which nothing
  // else detects (the dangerous error).
  bool floor_edge_unknown = true;
  // Labels: a floor sample within this many samples of an obstacle sample in its image column (the
  // obstacle's base below it, its top edge above it) or row (its sides) is unknown: its matching
  // window straddles the edge, and next to an obstacle the floor label reaches onto its lowest
  // pixels. More samples label fewer obstacle pixels floor and cover less of the floor. 0 = off.
  int edge_floor_unknown_samples = 1;
  // Labels: floor just below a drop-off's edge in its image column (a run of 3 drop-off
  // samples), within this many samples and this many metres (along the floor) of the
  // edge, is unknown. At a step's edge the upper floor's texture holds the windows that straddle
  // it (the coarse levels' wider ones too), and the floor label reaches up to about 20 px onto
  // the lower surface beyond, where the robot would fall. From farther away those pixels span more
  // floor than the map needs to lose (its votes settle the edge): hence the metres. 0 = off.
  int drop_off_edge_floor_unknown_samples = 5;
  double drop_off_edge_floor_unknown_m = 0.15;
  // Labels: unmeasured samples between two labelled ones in an image column are filled where the
  // two bound what lies between (one vertical surface, an obstacle standing on the floor, or
  // floor on both sides of a gap too short to hide an obstacle): FillColumnGaps in the .cc says
  // which rule fills what. Gaps of up to fill_max_gap_samples samples (0 = off); a floor
  // gap at most fill_max_floor_gap_m long on the floor (metres: a hole in it could not be
  // seen, so it is kept short).
  int fill_max_gap_samples = 24;
  double fill_max_floor_gap_m = 0.10;
  // Top view, surfaces: the obstacle (or drop-off) samples of one run in an image column (up to two
  // unmeasured ones between) show one surface, vertical (a wall, a box's side: one range) or
  // horizontal (a table top from below, the lower floor past a drop-off: one height). With at
  // least column_min_samples placeable samples in the run, a sample within column_max_sigmas
  // footprint sigmas (+ 0.05 m) of the run's median range goes to that range along its ray, else
  // one within column_max_sigmas height sigmas (+ 0.02 m) of the median height to where its ray
  // meets that height. The others are not placed; their cells are not free. A shorter run is too
  // short to show a surface: its obstacle samples keep their own footprints (a small obstacle;
  // leaving it out lets the floor around clear its cell), its drop-off samples are not placed
  // (lone false drop-offs are phantom cells). One sample's range scatters by several cells at
  // 1-3 m, the run's median much less: fewer phantom cells, at some recall (measurements:
  // docs/experiments.md). 0 = off (every sample at its own triangulated footprint), >= 0.
  int column_min_samples = 3;
  double column_max_sigmas = 2.0;  // >= 0
  // Top view: cells within this many cells (a square) of a placed obstacle point or of a floor
  // edge (floor_edge_samples) are not free in the local map: a wall's points sit a few cm behind
  // its base cell, which the floor samples just in front of it would otherwise vote free, and a
  // textureless wall has no points at all. 0 = off.
  int free_margin_cells = 1;
  // Top view, free space by rays: between two consecutive floor samples of an image column that
  // both vote free, the floor under the ray between them is free too (anything standing there
  // higher than camera height x (far - near) / far would have hidden the far sample; a few mm at
  // the sample spacing). Without it, only the cells a floor sample's point falls in are free, and
  // beyond 2 m the samples' rows lie several cells apart on the floor.
  bool free_between_floor_samples = true;
  // How samples are combined before labelling: each on its own, with the median height of their
  // neighbours, or with the median height of their superpixel (SLICO; the paper's segments).
  enum class Aggregation { kNone, kMedian, kSegments };
  Aggregation aggregation = Aggregation::kSegments;
  int median_radius = 1;          // samples, for kMedian
  double segment_size_px = 16.0;  // superpixel side, input pixels, for kSegments
  int segment_iterations = 2;     // SLIC iterations
  // Superpixels computed at 1 / 2^segment_level of the search resolution (0 or 1): 1 is about four
  // times cheaper, with segments of the same size in input pixels.
  int segment_level = 1;
  int segment_min_samples = 3;  // measured samples a segment needs to be labelled
  // A segment labelled obstacle whose measured samples are at least this fraction of its samples
  // labels its unmeasured (textureless) samples obstacle too, for kSegments; 1 = never.
  double segment_fill_fraction = 0.25;

  // Every field's key, range and meaning (the checks, the config file and --dump use it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};

// The robot-frame top view (the paper's step 6).
struct LocalMapOptions {
  double resolution_m = 0.05;  // cell side
  double min_x_m = -1.0;       // extent in the base frame of the current frame (min < max)
  double max_x_m = 7.0;
  double min_y_m = -4.0;
  double max_y_m = 4.0;

  // Every field's key, range and meaning (the checks, the config file and --dump use it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};

// Reference frame selection (the paper's step 1): keep a reference until the camera has moved
// enough for parallax.
struct PairSelectionOptions {
  double min_baseline_m = 0.10;  // camera centre travel between the pair
  int max_history = 20;          // frames kept to choose a reference from
  // When the robot stops (or creeps) after driving, the last frame far enough away for a pair
  // stays in the history while it is within 2 * min_baseline_m (the frames after it go instead),
  // so that a robot waiting keeps seeing what it saw while driving instead of going blind once
  // max_history frames have passed. Standing still before any driving still gives no pair
  // (unknown).
  bool hold_reference = true;
  // Largest yaw between the pair (rad). Turning pairs have little baseline for much image
  // motion and match badly; when no frame within this yaw has the baseline, the frame is
  // "no parallax" (unknown), as when standing still.
  double max_rotation_rad = 0.12;
  // Turning on the spot still moves the camera (it sits ahead of the axle, mount x): when no
  // reference qualifies above, the newest frame within turn_max_rotation_rad (rad) whose
  // camera centre lies at least turn_min_baseline_m away (m) is used: a narrow-baseline pair
  // that sees near obstacles (FrameResult::turn_pair tells). turn_max_rotation_rad 0 = off.
  double turn_min_baseline_m = 0.04;
  double turn_max_rotation_rad = 0.5;
  // A turning pair's reference did not see the side the turn brings into view (at 45 deg/s a
  // pair of 0.04 m spans 0.4 rad: 180 px of a 640 px image). There the newest frame at least
  // turn_side_min_baseline_m away (m, below turn_min_baseline_m; 0 = off) is matched too, for
  // the samples the turning pair did not measure: half the baseline, so half the parallax, but
  // half the side left unseen.
  double turn_side_min_baseline_m = 0.02;
  // Dense detection on every N-th usable frame; the others are only tracked for odometry
  // and carry the last detected frame's result. 2 halves the cost with obstacle updates at half
  // the camera rate. A frame farther from the last detected one than a carried result may go
  // (2 * min_baseline_m, max_rotation_rad) is detected whatever N says.
  int detect_every = 2;
  // Far pair: a detected frame is also matched against the newest frame at least
  // far_min_baseline_m back (m, 0 = off; within max_rotation_rad and max_history), and each
  // sample keeps the pair that measures its height more precisely, when the two agree. One pair's
  // parallax of a 3 cm height falls with the square of the distance (about 0.25 px at 2.3 m over
  // 0.1 m for a camera 0.4 m up): the far floor needs a longer baseline to be told from a low
  // obstacle, while the near floor needs a short one (it was below the far frame's view).
  double far_min_baseline_m = 0.30;
  // Close pair: a detected frame is also matched against the newest frame at least
  // close_min_baseline_m back (m; 0 = off, and unused unless below min_baseline_m), in the image
  // rows whose floor lies within close_max_range_baselines baselines of the main pair's (where
  // the main pair's near floor changes scale by more than 1 / close_max_range_baselines between
  // its frames); there its samples replace the main pair's. Only when both pairs' motions were
  // fitted, not for a turning or pitched pair. A 5 cm box 0.6 m ahead moves 14 % farther than the
  // floor around it: over 0.1 m that is several pixels under a 17 % change of scale, and the
  // windows match it where it stood in the reference.
  double close_min_baseline_m = 0.05;
  double close_max_range_baselines = 8.0;

  // Every field's key, range and meaning (the checks, the config file and --dump use it).
  void Describe(OptionVisitor& v);
  bool IsValid(std::string* error) const;
};

struct DetectorOptions {
  GroundMotionOptions ground_motion;
  DirectAlignmentOptions direct_alignment;  // the pair's motion refined on the floor's texture
  ZeroDisparityOptions zero_disparity;
  ClassificationOptions classification;
  HeightFilterOptions height_filter;      // heights fused over the detected frames
  MotionEvidenceOptions motion_evidence;  // dense flow against the static world, every frame
  MovingObjectOptions moving_objects;     // its regions placed on the floor and tracked
  LocalMapOptions local_map;
  PairSelectionOptions pair_selection;
  FloorFeatureOptions floor_features;  // computed on every kOk result (FrameResult::floor_features)
  // Leave the floor features to the caller: Detect keeps what they come from in
  // FrameResult::floor_feature_source and ComputeFloorFeatures computes them, for the frames that
  // need them (a mapper's keyframes, one frame in 7-14 in the simulated scenes). Set by the
  // program, not a config key.
  bool defer_floor_features = false;

  bool IsValid(std::string* error) const;
};

}  // namespace monoplane
