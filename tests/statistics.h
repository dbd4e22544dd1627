// Statistical tests for the stochastic code, in place of hand-tuned tolerances: Pearson's chi-square
// test of observed counts against expected ones (bins expected to hold fewer than 5 are pooled, as
// pbrt-v4's tests do), its p-value from the regularised upper incomplete gamma function, z-tests,
// and the Sidak correction that keeps the suite's false-alarm rate at alpha over m repeated tests.
#pragma once

#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

namespace penumbra::test {

// Significance of each of m tests so that the chance that any fails by chance is alpha.
inline double sidak(double alpha, int m) { return 1 - std::pow(1 - alpha, 1.0 / m); }

// Q(a, x) = Gamma(a, x) / Gamma(a): series below a + 1, Lentz's continued fraction above.
inline double upperIncompleteGammaQ(double a, double x) {
    if (x <= 0) return 1;
    const double logPrefix = a * std::log(x) - x - std::lgamma(a);
    if (x < a + 1) {
        double term = 1 / a, sum = term;
        for (int n = 1; n < 10000 && std::abs(term) > 1e-16 * std::abs(sum); ++n) {
            term *= x / (a + n);
            sum += term;
        }
        return 1 - sum * std::exp(logPrefix);
    }
    const double tiny = 1e-300;
    double b = x + 1 - a, c = 1 / tiny, d = 1 / b, h = d;
    for (int i = 1; i < 10000; ++i) {
        const double an = -i * (i - a);
        b += 2;
        d = an * d + b;
        if (std::abs(d) < tiny) d = tiny;
        c = b + an / c;
        if (std::abs(c) < tiny) c = tiny;
        d = 1 / d;
        const double delta = d * c;
        h *= delta;
        if (std::abs(delta - 1) < 1e-16) break;
    }
    return std::exp(logPrefix) * h;
}

struct ChiSquare {
    double statistic = 0;
    int degreesOfFreedom = 0;
    double pValue = 1;
};

// Observed counts against expected counts (same total). Bins expected below `minExpected` are pooled
// into one; the pooled bin joins the test if it reaches `minExpected` itself.
inline ChiSquare chiSquareTest(const std::vector<double>& observed, const std::vector<double>& expected,
                               double minExpected = 5) {
    ChiSquare r;
    double pooledObserved = 0, pooledExpected = 0;
    int bins = 0;
    for (size_t k = 0; k < observed.size(); ++k) {
        if (expected[k] < minExpected) {
            pooledObserved += observed[k];
            pooledExpected += expected[k];
            continue;
        }
        r.statistic += (observed[k] - expected[k]) * (observed[k] - expected[k]) / expected[k];
        ++bins;
    }
    if (pooledExpected >= minExpected) {
        r.statistic += (pooledObserved - pooledExpected) * (pooledObserved - pooledExpected) / pooledExpected;
        ++bins;
    } else if (pooledObserved > 10 * minExpected) {
        // Many samples where almost none are expected: the distribution is wrong.
        r.statistic = std::numeric_limits<double>::infinity();
    }
    r.degreesOfFreedom = std::max(1, bins - 1);
    r.pValue = std::isfinite(r.statistic) ? upperIncompleteGammaQ(0.5 * r.degreesOfFreedom, 0.5 * r.statistic) : 0;
    return r;
}

// The standard normal quantile (Acklam's rational approximation, relative error below 1.2e-9).
inline double normalQuantile(double p) {
    static const double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,  -2.759285104469687e+02,
                               1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
    static const double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                               6.680131188771972e+01, -1.328068155288572e+01};
    static const double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                               -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
    static const double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                               3.754408661907416e+00};
    const double low = 0.02425;
    if (p < low) {
        const double q = std::sqrt(-2 * std::log(p));
        return (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
               ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
    }
    if (p > 1 - low) return -normalQuantile(1 - p);
    const double q = p - 0.5, r = q * q;
    return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
           (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
}

// |z| below which a two-sided z-test at significance alpha passes.
inline double zLimit(double alpha) { return normalQuantile(1 - alpha / 2); }

}  // namespace penumbra::test
