// CGAL's optimal oriented bounding box, the quality reference (and the slow --obb cgal mode). Kept in its own
// translation unit: CGAL is slow to compile, and GPL-licensed (the tool is GPL; runtime/ never sees this).
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/optimal_bounding_box.h>

#include <Eigen/SVD>

#include <vector>

namespace cb {

bool cgal_optimal_frame(const double* pts, size_t n, double frame[3][3]) {
    using K = CGAL::Exact_predicates_inexact_constructions_kernel;
    if (n < 4) return false;  // CGAL's fitter needs a 3-D hull
    // Flat or collinear sets have no 3-D hull either: leave them to the min-area rectangle fit.
    Eigen::MatrixXd m(n, 3);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (size_t v = 0; v < n; ++v) mean += Eigen::Vector3d(pts[v * 3], pts[v * 3 + 1], pts[v * 3 + 2]);
    mean /= double(n);
    for (size_t v = 0; v < n; ++v)
        for (int k = 0; k < 3; ++k) m(Eigen::Index(v), k) = pts[v * 3 + k] - mean[k];
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(m);
    if (!(svd.singularValues()[2] > 1e-9 * svd.singularValues()[0])) return false;

    std::vector<K::Point_3> points;
    points.reserve(n);
    for (size_t v = 0; v < n; ++v) points.emplace_back(pts[v * 3], pts[v * 3 + 1], pts[v * 3 + 2]);
    K::Aff_transformation_3 to_box;
    CGAL::oriented_bounding_box(points, to_box, CGAL::parameters::random_seed(0));
    // The transformation rotates the box onto the coordinate axes: its rows are the box axes.
    for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k) frame[i][k] = CGAL::to_double(to_box.m(i, k));
    return true;
}

}  // namespace cb
