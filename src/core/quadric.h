// Garland-Heckbert error quadric: the sum of squared distances to a set of planes, as a symmetric 4x4
// matrix stored by its 10 distinct entries, in double (the sums of many small planes lose precision
// in float).
#pragma once
#include <array>
#include <cmath>

namespace vdb_isosimp {

struct Quadric {
    // xx xy xz xw yy yz yw zz zw ww
    std::array<double, 10> q{};

    // Adds the plane n·x + d = 0 (n unit) with weight w (the face's area, so big faces count more).
    void addPlane(const std::array<double, 3>& n, double d, double w)
    {
        const double a = n[0], b = n[1], c = n[2];
        q[0] += w * a * a; q[1] += w * a * b; q[2] += w * a * c; q[3] += w * a * d;
        q[4] += w * b * b; q[5] += w * b * c; q[6] += w * b * d;
        q[7] += w * c * c; q[8] += w * c * d; q[9] += w * d * d;
    }

    // Adds w times the squared distance to the origin of the quadric's coordinates (the point it is
    // written around).
    void addPoint(double w)
    {
        q[0] += w;
        q[4] += w;
        q[7] += w;
    }

    Quadric& operator+=(const Quadric& o)
    {
        for (int i = 0; i < 10; ++i) q[i] += o.q[i];
        return *this;
    }

    double error(const std::array<double, 3>& p) const
    {
        const double x = p[0], y = p[1], z = p[2];
        return q[0] * x * x + 2 * q[1] * x * y + 2 * q[2] * x * z + 2 * q[3] * x + q[4] * y * y +
               2 * q[5] * y * z + 2 * q[6] * y + q[7] * z * z + 2 * q[8] * z + q[9];
    }

    // The same quadric in coordinates shifted by `delta` (y = y' + delta): with Q written around a
    // point o, the result is Q written around o + delta.
    Quadric shifted(const std::array<double, 3>& delta) const
    {
        const double x = delta[0], y = delta[1], z = delta[2];
        Quadric r = *this;
        r.q[3] = q[0] * x + q[1] * y + q[2] * z + q[3];
        r.q[6] = q[1] * x + q[4] * y + q[5] * z + q[6];
        r.q[8] = q[2] * x + q[5] * y + q[7] * z + q[8];
        r.q[9] = error(delta);
        return r;
    }

    // The point minimising the error, when the 3x3 system is well conditioned relative to its scale.
    bool optimum(std::array<double, 3>& p) const
    {
        const double a = q[0], b = q[1], c = q[2], d = q[4], e = q[5], f = q[7];
        const double c00 = d * f - e * e, c01 = c * e - b * f, c02 = b * e - c * d;
        const double det = a * c00 + b * c01 + c * c02;
        const double scale = a + d + f;
        if (!(std::abs(det) > 1e-10 * scale * scale * scale)) return false;
        const double c11 = a * f - c * c, c12 = b * c - a * e, c22 = a * d - b * b;
        const double rx = -q[3], ry = -q[6], rz = -q[8];
        const double inv = 1.0 / det;
        p = {(c00 * rx + c01 * ry + c02 * rz) * inv, (c01 * rx + c11 * ry + c12 * rz) * inv,
             (c02 * rx + c12 * ry + c22 * rz) * inv};
        return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]);
    }
};

} // namespace vdb_isosimp
