// Attribute error quadric (Hoppe, "New quadric metric for simplifying meshes with appearance
// attributes", 1999, for one scalar attribute): each face carries the attribute as a linear function
// over it, a(p) = g.p + d, and the quadric sums w (g.p + d - s)^2 over the faces merged into a vertex.
// At a placement p the best attribute value s is their weighted mean, and what is left, the weighted
// variance of the faces' predictions at p, is the cost: small where the merged faces agree on the
// attribute there, large across a front.
#pragma once
#include <algorithm>
#include <array>

namespace vdb_isosimp {

struct AttributeQuadric {
    // Sums of w g g^T (xx xy xz yy yz zz), w g, w g d, w, w d, w d^2.
    std::array<double, 6> gg{};
    std::array<double, 3> g{}, gd{};
    double w = 0.0, d = 0.0, dd = 0.0;

    // Adds a face's linear attribute with gradient `grad` and value `value` at the quadric's origin.
    void addFace(const std::array<double, 3>& grad, double value, double weight)
    {
        const double x = grad[0], y = grad[1], z = grad[2];
        gg[0] += weight * x * x; gg[1] += weight * x * y; gg[2] += weight * x * z;
        gg[3] += weight * y * y; gg[4] += weight * y * z; gg[5] += weight * z * z;
        for (int k = 0; k < 3; ++k) {
            g[k] += weight * grad[k];
            gd[k] += weight * grad[k] * value;
        }
        w += weight;
        d += weight * value;
        dd += weight * value * value;
    }

    AttributeQuadric& operator+=(const AttributeQuadric& o)
    {
        for (int k = 0; k < 6; ++k) gg[k] += o.gg[k];
        for (int k = 0; k < 3; ++k) {
            g[k] += o.g[k];
            gd[k] += o.gd[k];
        }
        w += o.w;
        d += o.d;
        dd += o.dd;
        return *this;
    }

    // G p: the gradient sum's quadratic form applied to p.
    std::array<double, 3> ggTimes(const std::array<double, 3>& p) const
    {
        return {gg[0] * p[0] + gg[1] * p[1] + gg[2] * p[2], gg[1] * p[0] + gg[3] * p[1] + gg[4] * p[2],
                gg[2] * p[0] + gg[4] * p[1] + gg[5] * p[2]};
    }

    // The same quadric written around the point `delta` of its coordinates (as Quadric::shifted): each
    // face's value there is d + g.delta.
    AttributeQuadric shifted(const std::array<double, 3>& delta) const
    {
        AttributeQuadric r = *this;
        const std::array<double, 3> gp = ggTimes(delta);
        const double gDelta = g[0] * delta[0] + g[1] * delta[1] + g[2] * delta[2];
        const double gdDelta = gd[0] * delta[0] + gd[1] * delta[1] + gd[2] * delta[2];
        for (int k = 0; k < 3; ++k) r.gd[k] = gd[k] + gp[k];
        r.d = d + gDelta;
        r.dd = dd + 2 * gdDelta + (gp[0] * delta[0] + gp[1] * delta[1] + gp[2] * delta[2]);
        return r;
    }

    // min over s of sum w (g.p + d - s)^2: the weighted variance of the faces' values at p, times w.
    double error(const std::array<double, 3>& p) const
    {
        if (!(w > 0)) return 0.0;
        const AttributeQuadric at = shifted(p);
        return std::max(0.0, at.dd - at.d * at.d / at.w);
    }
};

} // namespace vdb_isosimp
