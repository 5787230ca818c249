// Small fixed-size vectors used by the mesh model. Storage types are float (what files carry);
// algorithms that need precision convert to double locally (see metric/ and eval/).
#pragma once

#include <array>
#include <cmath>
#include <cstdint>

namespace lodforge {

template <typename T, int N>
struct Vec {
  std::array<T, N> v{};

  constexpr T& operator[](int i) { return v[static_cast<std::size_t>(i)]; }
  constexpr const T& operator[](int i) const { return v[static_cast<std::size_t>(i)]; }
  friend constexpr bool operator==(const Vec&, const Vec&) = default;

  friend constexpr Vec operator+(Vec a, const Vec& b) {
    for (int i = 0; i < N; ++i) a[i] += b[i];
    return a;
  }
  friend constexpr Vec operator-(Vec a, const Vec& b) {
    for (int i = 0; i < N; ++i) a[i] -= b[i];
    return a;
  }
  friend constexpr Vec operator*(Vec a, T s) {
    for (int i = 0; i < N; ++i) a[i] *= s;
    return a;
  }
  friend constexpr Vec operator*(T s, Vec a) { return a * s; }
};

using Vec2f = Vec<float, 2>;
using Vec3f = Vec<float, 3>;
using Vec4f = Vec<float, 4>;
using Vec3d = Vec<double, 3>;

template <typename T, int N>
constexpr T dot(const Vec<T, N>& a, const Vec<T, N>& b) {
  T s{};
  for (int i = 0; i < N; ++i) s += a[i] * b[i];
  return s;
}

template <typename T>
constexpr Vec<T, 3> cross(const Vec<T, 3>& a, const Vec<T, 3>& b) {
  return {{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}};
}

template <typename T, int N>
T length(const Vec<T, N>& a) {
  return std::sqrt(dot(a, a));
}

inline Vec3d to_double(const Vec3f& a) { return {{a[0], a[1], a[2]}}; }
inline Vec3f to_float(const Vec3d& a) {
  return {{static_cast<float>(a[0]), static_cast<float>(a[1]), static_cast<float>(a[2])}};
}

// Axis-aligned bounding box; empty until the first point is added.
struct Bounds3 {
  Vec3d min{{INFINITY, INFINITY, INFINITY}};
  Vec3d max{{-INFINITY, -INFINITY, -INFINITY}};

  void add(const Vec3d& p) {
    for (int i = 0; i < 3; ++i) {
      min[i] = std::fmin(min[i], p[i]);
      max[i] = std::fmax(max[i], p[i]);
    }
  }
  bool empty() const { return !(min[0] <= max[0]); }
  double diagonal() const { return empty() ? 0.0 : length(max - min); }
};

}  // namespace lodforge
