// Benchmark-only driver: times MRPT's data_association_full_covariance on one problem read from
// stdin and prints its answer, for benchmarks/mrpt_compare.py (built there with g++; not part of
// the package).
//
// stdin:  m n d method(nn|jcbb) kdtree(0|1) repeats chi2quantile, then z (m x d), zhat (n x d)
//         and the innovation covariance S = P + blockdiag(R) ((n d) x (n d)), row-major.
// stdout: "ms <best of the repeats>", "nodes <JCBB nodes>", "compatible <pairs in its gate>",
//         then one "pair <feature> <landmark>" line per association.
#include <mrpt/math/CMatrixDynamic.h>
#include <mrpt/slam/data_association.h>

#include <chrono>
#include <cstdio>
#include <iostream>
#include <limits>
#include <string>

int main()
{
	size_t m, n, d, repeats;
	std::string method;
	int kdtree;
	double quantile;
	if (!(std::cin >> m >> n >> d >> method >> kdtree >> repeats >> quantile)) return 2;
	mrpt::math::CMatrixDouble z(m, d), zhat(n, d), S(n * d, n * d);
	for (size_t i = 0; i < m; i++)
		for (size_t a = 0; a < d; a++) std::cin >> z(i, a);
	for (size_t j = 0; j < n; j++)
		for (size_t a = 0; a < d; a++) std::cin >> zhat(j, a);
	for (size_t r = 0; r < n * d; r++)
		for (size_t c = 0; c < n * d; c++) std::cin >> S(r, c);
	if (!std::cin) return 2;
	const auto how = method == "jcbb" ? mrpt::slam::assocJCBB : mrpt::slam::assocNN;
	mrpt::slam::TDataAssociationResults results;
	double best = std::numeric_limits<double>::infinity();
	for (size_t r = 0; r < repeats; r++)
	{
		results.clear();
		const auto start = std::chrono::steady_clock::now();
		mrpt::slam::data_association_full_covariance(
			z, zhat, S, results, how, mrpt::slam::metricMaha, quantile, kdtree != 0);
		const std::chrono::duration<double, std::milli> took = std::chrono::steady_clock::now() - start;
		best = std::min(best, took.count());
	}
	size_t compatible = 0;
	for (int r = 0; r < results.indiv_compatibility.rows(); r++)
		for (int c = 0; c < results.indiv_compatibility.cols(); c++) compatible += results.indiv_compatibility(r, c) ? 1 : 0;
	std::printf("ms %.6f\nnodes %zu\ncompatible %zu\n", best, results.nNodesExploredInJCBB, compatible);
	for (const auto& [feature, landmark] : results.associations) std::printf("pair %zu %zu\n", feature, landmark);
	return 0;
}
