#pragma once
// Rigid transforms and the SO(3)/SE(3) maps used across msmcal.
//
// Naming follows COLMAP: `cam_from_world` maps a point given in {world} to {cam}:
//   p_in_cam = cam_from_world * p_in_world.
// The minimal form of a transform is the paper's T~ = [Log(R)^T t^T]^T (rotation vector in
// radians, translation in millimetres), not the SE(3) twist.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace msmcal::geometry {

// Exp: rotation vector (radians, axis * angle) -> rotation matrix. Exact near zero.
Eigen::Matrix3d So3Exp(const Eigen::Vector3d& rotation_vector);
// Log: rotation matrix -> rotation vector with angle in [0, pi]. Exact near 0 and near pi.
Eigen::Vector3d So3Log(const Eigen::Matrix3d& rotation);
// Skew-symmetric matrix [v]x such that [v]x * w = v x w.
Eigen::Matrix3d Skew(const Eigen::Vector3d& v);

struct Rigid3d {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Rigid3d() = default;
  Rigid3d(const Eigen::Quaterniond& r, const Eigen::Vector3d& t) : rotation(r.normalized()), translation(t) {}
  Rigid3d(const Eigen::Matrix3d& r, const Eigen::Vector3d& t)
      : rotation(Eigen::Quaterniond(r).normalized()), translation(t) {}

  Eigen::Matrix3d RotationMatrix() const { return rotation.toRotationMatrix(); }
  Eigen::Matrix4d ToMatrix() const;
  Rigid3d Inverse() const;
  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return rotation * p + translation; }
  // Composition: (a_from_b * b_from_c) = a_from_c.
  Rigid3d operator*(const Rigid3d& b_from_c) const;

  // The paper's 6-vector [Log(R); t] and back.
  Eigen::Matrix<double, 6, 1> ToMinimal() const;
  static Rigid3d FromMinimal(const Eigen::Matrix<double, 6, 1>& x);
};

// Rotation angle between two rotations, radians.
double RotationDistance(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b);

}  // namespace msmcal::geometry
