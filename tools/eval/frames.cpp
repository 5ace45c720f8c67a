// Frame names, placing known frames from truth, and the rigid best fit for relative frames.
#include "locus/eval/frames.hpp"

#include <charconv>
#include <cmath>
#include <stdexcept>

namespace locus::eval {

namespace {

const char* kExpected =
    "expected world, body, relative, relative_trace, <name>_start[@T], <name>_origin[@T] or <name>_north[@T] "
    "(T = seconds on the reference's clock; see docs/eval.md)";

bool ends_with(std::string_view s, std::string_view suffix) {
  return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

}  // namespace

bool FrameSpec::needs_reference() const noexcept {
  return kind == FrameKind::Start || kind == FrameKind::Origin || kind == FrameKind::North || kind == FrameKind::Body;
}

FrameSpec parse_frame(std::string_view name) {
  FrameSpec f;
  f.name = std::string(name);
  std::string_view base = name;
  const auto at = name.find('@');
  if (at != std::string_view::npos) {
    base = name.substr(0, at);
    const std::string_view t = name.substr(at + 1);
    double v = 0.0;
    const auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (t.empty() || ec != std::errc() || ptr != t.data() + t.size() || !std::isfinite(v))
      throw std::invalid_argument("frame '" + f.name + "': '@" + std::string(t) +
                                  "' is not a time (expected @<seconds on the reference's clock>, e.g. player_start@12.5)");
    f.t0_local_s = v;
  }
  auto plain = [&](FrameKind k) {
    if (f.t0_local_s) throw std::invalid_argument("frame '" + f.name + "': '" + std::string(base) + "' takes no @T suffix");
    f.kind = k;
    return f;
  };
  if (base == "world") return plain(FrameKind::World);
  if (base == "body") return plain(FrameKind::Body);
  if (base == "relative") return plain(FrameKind::Relative);
  if (base == "relative_trace") return plain(FrameKind::RelativeTrace);
  struct Suffix {
    std::string_view text;
    FrameKind kind;
  };
  for (const Suffix s : {Suffix{"_start", FrameKind::Start}, Suffix{"_origin", FrameKind::Origin}, Suffix{"_north", FrameKind::North}}) {
    if (ends_with(base, s.text) && base.size() > s.text.size()) {
      f.kind = s.kind;
      return f;
    }
  }
  throw std::invalid_argument("frame '" + f.name + "' is unknown: " + kExpected);
}

Eigen::Matrix3d heading_axes(const Eigen::Quaterniond& attitude) {
  const Vec3 up = Vec3::UnitZ();
  Vec3 y = attitude * Vec3::UnitY();
  y.z() = 0.0;
  if (y.norm() < 0.2) {  // body y within ~11.5° of vertical: the screen faces the user, forward = −z
    y = -(attitude * Vec3::UnitZ());
    y.z() = 0.0;
  }
  if (y.norm() < 1e-9) y = Vec3::UnitY();  // unreachable for a unit quaternion, kept for safety
  y.normalize();
  Eigen::Matrix3d axes;
  axes.col(0) = y.cross(up);
  axes.col(1) = y;
  axes.col(2) = up;
  return axes;
}

FramePlacement place_frame(const FrameSpec& frame, const std::string& reference, double t_true_s, const TruthData& truth) {
  FramePlacement p;
  if (frame.kind == FrameKind::World) return p;
  if (frame.aligned()) throw std::logic_error("place_frame: frame '" + frame.name + "' is only known up to a rigid transform");
  if (reference.empty()) throw std::runtime_error("frame '" + frame.name + "' needs a reference device");
  if (!truth.has_truth(reference))
    throw std::runtime_error("frame '" + frame.name + "': no truth trajectory (truth.csv) or anchor for reference '" + reference + "'");
  if (frame.kind == FrameKind::Body) {
    const TruthPose pose = *truth.pose(reference, t_true_s);
    p.origin_m = pose.position_m;
    p.axes = pose.attitude.toRotationMatrix();
    return p;
  }
  double t0 = 0.0;
  if (frame.t0_local_s) {
    t0 = truth.clock(reference).true_from_local(*frame.t0_local_s);
  } else {
    auto it = truth.tracks.find(reference);
    t0 = (it != truth.tracks.end() && !it->second.empty()) ? it->second.t_begin_s() : 0.0;
  }
  const TruthPose pose = *truth.pose(reference, t0);
  p.origin_m = pose.position_m;
  switch (frame.kind) {
    case FrameKind::Start:
      p.axes = heading_axes(pose.attitude);
      break;
    case FrameKind::Origin:
      p.axes.setIdentity();
      break;
    case FrameKind::North: {
      if (!truth.magnetic_field_world_ut)
        throw std::runtime_error("frame '" + frame.name + "' needs truth.magnetic_field_world in scene.yaml");
      Vec3 north = *truth.magnetic_field_world_ut;
      north.z() = 0.0;
      if (north.norm() < 1e-9) throw std::runtime_error("frame '" + frame.name + "': truth.magnetic_field_world has no horizontal part");
      north.normalize();
      p.axes.col(0) = north.cross(Vec3::UnitZ());
      p.axes.col(1) = north;
      p.axes.col(2) = Vec3::UnitZ();
      break;
    }
    default:
      break;
  }
  return p;
}

RigidFit fit_rigid(const std::vector<Vec3>& src, const std::vector<Vec3>& dst, int dims) {
  if (src.size() != dst.size() || src.empty()) throw std::invalid_argument("fit_rigid: need equally many points, at least one");
  if (dims != 2 && dims != 3) throw std::invalid_argument("fit_rigid: dims must be 2 or 3");
  const double n = static_cast<double>(src.size());
  Vec3 cs = Vec3::Zero(), cd = Vec3::Zero();
  for (std::size_t i = 0; i < src.size(); ++i) {
    cs += src[i];
    cd += dst[i];
  }
  cs /= n;
  cd /= n;
  RigidFit fit;
  if (dims == 2) {
    cs.z() = cd.z() = 0.0;
    Eigen::Matrix2d h = Eigen::Matrix2d::Zero();
    for (std::size_t i = 0; i < src.size(); ++i)
      h += (src[i] - cs).head<2>() * (dst[i] - cd).head<2>().transpose();
    Eigen::JacobiSVD<Eigen::Matrix2d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix2d d = Eigen::Matrix2d::Identity();
    d(1, 1) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1.0 : 1.0;
    const Eigen::Matrix2d r = svd.matrixV() * d * svd.matrixU().transpose();
    fit.rotation.setIdentity();
    fit.rotation.topLeftCorner<2, 2>() = r;
  } else {
    Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
    for (std::size_t i = 0; i < src.size(); ++i) h += (src[i] - cs) * (dst[i] - cd).transpose();
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
    d(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1.0 : 1.0;
    fit.rotation = svd.matrixV() * d * svd.matrixU().transpose();
  }
  fit.translation = cd - fit.rotation * cs;
  return fit;
}

}  // namespace locus::eval
