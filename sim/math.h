#pragma once
// Small fixed-size linear algebra types shared by the solver. Particle and
// grid data are single precision; tests instantiate templates in double.
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace triad {

template <class T>
using Vec3 = Eigen::Matrix<T, 3, 1>;
template <class T>
using Mat3 = Eigen::Matrix<T, 3, 3>;
template <class T>
using Mat9 = Eigen::Matrix<T, 9, 9>;

using Vec3f = Vec3<float>;
using Mat3f = Mat3<float>;
using Vec3d = Vec3<double>;
using Mat3d = Mat3<double>;
using Vec3i = Eigen::Vector3i;
using Quatd = Eigen::Quaterniond;

}  // namespace triad
