// The error quadric (core/quadric.h) against direct geometry: squared distances to its planes, the
// shift of the point it is written around, and the optimum where planes meet. The attribute quadric
// (core/attribute_quadric.h) against the variance of its faces' linear predictions, computed directly.
#include "core/attribute_quadric.h"
#include "core/quadric.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

using namespace vdb_isosimp;

namespace {

std::array<double, 3> unit(std::array<double, 3> v)
{
    const double l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    return {v[0] / l, v[1] / l, v[2] / l};
}

double dot(const std::array<double, 3>& a, const std::array<double, 3>& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// Seven random linear terms v.x + d, weight w in [0.1, 0.9]: planes (v unit) or faces' attribute
// functions (v the gradient).
struct LinearTerm {
    std::array<double, 3> v;
    double d, w;
};
std::vector<LinearTerm> randomTerms(std::mt19937& rng, bool unitVectors)
{
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<LinearTerm> terms;
    for (int i = 0; i < 7; ++i) {
        const std::array<double, 3> v{u(rng), u(rng), u(rng)};
        const LinearTerm t{unitVectors ? unit(v) : v, u(rng), 0.5 + u(rng) * 0.4};
        terms.push_back(t);
    }
    return terms;
}

} // namespace

TEST(Quadric, ErrorIsTheWeightedSumOfSquaredPlaneDistances)
{
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const std::vector<LinearTerm> planes = randomTerms(rng, true);
    Quadric q;
    for (const LinearTerm& p : planes) q.addPlane(p.v, p.d, p.w);
    for (int k = 0; k < 20; ++k) {
        const std::array<double, 3> x{u(rng) * 3, u(rng) * 3, u(rng) * 3};
        double expected = 0.0;
        for (const LinearTerm& p : planes) expected += p.w * (dot(p.v, x) + p.d) * (dot(p.v, x) + p.d);
        EXPECT_NEAR(q.error(x), expected, 1e-12 * (1.0 + expected));
        // Written around x, the quadric gives at its origin what it gave at x.
        EXPECT_NEAR(q.shifted(x).error({0, 0, 0}), expected, 1e-12 * (1.0 + expected));
        Quadric sum = q;
        sum += q;
        EXPECT_NEAR(sum.error(x), 2 * expected, 2e-12 * (1.0 + expected));
    }
}

TEST(Quadric, OptimumIsWhereThreePlanesMeet)
{
    // The corner (1, 2, 3) of three slanted planes.
    const std::array<double, 3> corner{1, 2, 3};
    Quadric q;
    for (const auto& n : {unit({1, 0.2, 0}), unit({0, 1, 0.3}), unit({0.1, 0, 1})}) q.addPlane(n, -dot(n, corner), 1.0);
    std::array<double, 3> p{};
    ASSERT_TRUE(q.optimum(p));
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(p[a], corner[a], 1e-9);
    EXPECT_NEAR(q.error(p), 0.0, 1e-18);
}

TEST(Quadric, NoOptimumAlongAnEdgeOrOnAPlane)
{
    // Two planes meet in a line and one plane is a plane: no single point minimises either, and the
    // optimum says so instead of returning a far-off point.
    Quadric edge;
    edge.addPlane({1, 0, 0}, -1.0, 1.0);
    edge.addPlane({0, 1, 0}, -2.0, 1.0);
    std::array<double, 3> p{};
    EXPECT_FALSE(edge.optimum(p));
    Quadric flat;
    flat.addPlane({0, 0, 1}, 0.5, 2.0);
    EXPECT_FALSE(flat.optimum(p));
    // A point term makes it well posed: the point nearest the quadric's origin on the edge line.
    edge.addPoint(1e-3);
    ASSERT_TRUE(edge.optimum(p));
    EXPECT_NEAR(p[0], 1.0, 1e-2);
    EXPECT_NEAR(p[1], 2.0, 1e-2);
    EXPECT_NEAR(p[2], 0.0, 1e-9);
}

TEST(AttributeQuadric, ErrorIsTheWeightedVarianceOfTheFacesPredictions)
{
    std::mt19937 rng(9);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const std::vector<LinearTerm> faces = randomTerms(rng, false);
    AttributeQuadric q;
    for (const LinearTerm& f : faces) q.addFace(f.v, f.d, f.w);
    for (int t = 0; t < 20; ++t) {
        const std::array<double, 3> p{u(rng) * 3, u(rng) * 3, u(rng) * 3};
        double sw = 0, mean = 0;
        for (const LinearTerm& f : faces) {
            sw += f.w;
            mean += f.w * (dot(f.v, p) + f.d);
        }
        mean /= sw;
        double variance = 0;
        for (const LinearTerm& f : faces) variance += f.w * (dot(f.v, p) + f.d - mean) * (dot(f.v, p) + f.d - mean);
        EXPECT_NEAR(q.error(p), variance, 1e-9 * (1 + variance));
        // Written around another point, the same quadric gives the same error at the same place.
        const std::array<double, 3> delta{u(rng), u(rng), u(rng)};
        EXPECT_NEAR(q.shifted(delta).error({p[0] - delta[0], p[1] - delta[1], p[2] - delta[2]}), variance, 1e-9 * (1 + variance));
    }
}

TEST(AttributeQuadric, OneLinearFieldCostsNothingAFrontDoes)
{
    // Faces sampling one linear field agree everywhere; two sides of a front do not.
    AttributeQuadric same, front;
    const std::array<double, 3> g{0.3, -0.2, 0.1};
    for (double w : {1.0, 2.0, 0.5}) same.addFace(g, 1.5, w);
    front.addFace({0, 0, 0}, -1.0, 1.0);
    front.addFace({0, 0, 0}, 1.0, 1.0);
    for (const std::array<double, 3>& p : {std::array<double, 3>{0, 0, 0}, {2, -1, 4}}) {
        EXPECT_NEAR(same.error(p), 0.0, 1e-12);
        EXPECT_NEAR(front.error(p), 2.0, 1e-12);  // values -1 and 1 around their mean 0, weight 1 each
    }
}
