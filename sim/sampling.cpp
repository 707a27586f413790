#include "sim/sampling.h"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace rtsim {

namespace {

constexpr size_t kMinRegressionUnits = 10;

// Continued fraction for the regularised incomplete beta I_x(a, b) (modified Lentz), valid and
// quickly convergent for x < (a + 1) / (a + b + 2).
double beta_continued_fraction(double a, double b, double x) {
    constexpr double kTiny = 1e-300, kEps = 1e-15;
    const double qab = a + b, qap = a + 1.0, qam = a - 1.0;
    double c = 1.0, d = 1.0 - qab * x / qap;
    if (std::fabs(d) < kTiny) d = kTiny;
    d = 1.0 / d;
    double h = d;
    for (int m = 1; m <= 500; ++m) {
        const int m2 = 2 * m;
        double aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        d = 1.0 + aa * d;
        if (std::fabs(d) < kTiny) d = kTiny;
        c = 1.0 + aa / c;
        if (std::fabs(c) < kTiny) c = kTiny;
        d = 1.0 / d;
        h *= d * c;
        aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        d = 1.0 + aa * d;
        if (std::fabs(d) < kTiny) d = kTiny;
        c = 1.0 + aa / c;
        if (std::fabs(c) < kTiny) c = kTiny;
        d = 1.0 / d;
        const double del = d * c;
        h *= del;
        if (std::fabs(del - 1.0) < kEps) break;
    }
    return h;
}

double regularized_incomplete_beta(double a, double b, double x) {
    if (x <= 0.0) return 0.0;
    if (x >= 1.0) return 1.0;
    const double log_front =
        std::lgamma(a + b) - std::lgamma(a) - std::lgamma(b) + a * std::log(x) + b * std::log1p(-x);
    const double front = std::exp(log_front);
    if (x < (a + 1.0) / (a + b + 2.0)) return front * beta_continued_fraction(a, b, x) / a;
    return 1.0 - front * beta_continued_fraction(b, a, 1.0 - x) / b;
}

double t_quantile_for(double confidence, uint64_t n) {
    return student_t_quantile(0.5 + confidence / 2.0, double(n - 1));
}

}  // namespace

double student_t_cdf(double t, double df) {
    const double x = df / (df + t * t);
    const double tail = 0.5 * regularized_incomplete_beta(df / 2.0, 0.5, x);
    return t >= 0 ? 1.0 - tail : tail;
}

double student_t_quantile(double p, double df) {
    if (!(p > 0.0 && p < 1.0) || !(df >= 1.0))
        throw std::invalid_argument("student_t_quantile: p in (0, 1) and df >= 1");
    if (p == 0.5) return 0.0;
    // Bisection on the CDF: monotone and safe; 200 halvings reach double precision.
    double lo = 0.0, hi = 1.0;
    const double target = p > 0.5 ? p : 1.0 - p;
    while (student_t_cdf(hi, df) < target) hi *= 2.0;
    for (int i = 0; i < 200 && hi - lo > 1e-14 * hi; ++i) {
        const double mid = 0.5 * (lo + hi);
        (student_t_cdf(mid, df) < target ? lo : hi) = mid;
    }
    const double t = 0.5 * (lo + hi);
    return p > 0.5 ? t : -t;
}

double Estimate::relative_half_width() const {
    if (value != 0.0) return half_width / std::fabs(value);
    return half_width == 0.0 ? 0.0 : std::numeric_limits<double>::infinity();
}

Estimate mean_estimate(const std::vector<double>& x, uint64_t population, double confidence) {
    Estimate e;
    e.confidence = confidence;
    e.units = x.size();
    e.population = population;
    if (x.empty()) return e;
    double sum = 0;
    for (double v : x) sum += v;
    e.value = sum / double(x.size());
    if (x.size() < 2) {
        e.half_width = x.size() == population ? 0.0 : std::numeric_limits<double>::infinity();
        return e;
    }
    double ss = 0;
    for (double v : x) ss += (v - e.value) * (v - e.value);
    const double n = double(x.size());
    const double variance = ss / (n - 1.0);
    const double fpc = population > 0 ? std::max(0.0, 1.0 - n / double(population)) : 1.0;
    e.half_width = t_quantile_for(confidence, x.size()) * std::sqrt(variance / n * fpc);
    return e;
}

Estimate ratio_estimate(const std::vector<double>& y, const std::vector<double>& x,
                        uint64_t population, double confidence) {
    if (y.size() != x.size()) throw std::invalid_argument("ratio_estimate: y and x differ in size");
    Estimate e;
    e.confidence = confidence;
    e.units = x.size();
    e.population = population;
    double sy = 0, sx = 0;
    for (size_t i = 0; i < x.size(); ++i) {
        sy += y[i];
        sx += x[i];
    }
    if (x.empty() || sx == 0.0) {
        e.half_width = std::numeric_limits<double>::infinity();
        return e;
    }
    e.value = sy / sx;
    if (x.size() < 2) {
        e.half_width = x.size() == population ? 0.0 : std::numeric_limits<double>::infinity();
        return e;
    }
    const double n = double(x.size());
    const double mean_x = sx / n;
    double ss = 0;  // residuals of the ratio model y = R x
    for (size_t i = 0; i < x.size(); ++i) {
        const double r = y[i] - e.value * x[i];
        ss += r * r;
    }
    const double fpc = population > 0 ? std::max(0.0, 1.0 - n / double(population)) : 1.0;
    const double variance = ss / (n - 1.0) / (n * mean_x * mean_x) * fpc;
    e.half_width = t_quantile_for(confidence, x.size()) * std::sqrt(variance);
    return e;
}

Estimate regression_total(const std::vector<double>& y, const std::vector<double>& x1,
                          const std::vector<double>& x2, double total_x1, double total_x2,
                          uint64_t population, double confidence) {
    if (y.size() != x1.size() || y.size() != x2.size())
        throw std::invalid_argument("regression_total: y, x1 and x2 differ in size");
    Estimate e;
    e.confidence = confidence;
    e.units = y.size();
    e.population = population;
    // Weighted least squares with the residual variance proportional to x1, the ratio
    // estimator's model (with x2 = 0 the fit is sum(y) / sum(x1)).
    double s11 = 0, s12 = 0, s22 = 0, s1y = 0, s2y = 0;
    for (size_t i = 0; i < y.size(); ++i) {
        const double w = x1[i] > 0 ? 1.0 / x1[i] : 1.0;
        s11 += w * x1[i] * x1[i];
        s12 += w * x1[i] * x2[i];
        s22 += w * x2[i] * x2[i];
        s1y += w * x1[i] * y[i];
        s2y += w * x2[i] * y[i];
    }
    // Two regressors when they are not (nearly) collinear and enough units measured; else one.
    const double det = s11 * s22 - s12 * s12;
    double b1 = 0, b2 = 0;
    int params = 0;
    // Below 10 units the second auxiliary is left out: its fit has too few degrees of freedom.
    // (Intervals from fewer than about 30 units under-cover either way: bench_sampled.py.)
    if (y.size() >= kMinRegressionUnits && s22 > 0 && det > 1e-9 * s11 * s22) {
        b1 = (s1y * s22 - s2y * s12) / det;
        b2 = (s2y * s11 - s1y * s12) / det;
        params = 2;
    } else if (s11 > 0) {
        b1 = s1y / s11;
        params = 1;
    } else {
        e.half_width = std::numeric_limits<double>::infinity();
        return e;
    }
    e.value = b1 * total_x1 + b2 * total_x2;
    const double n = double(y.size());
    if (y.size() <= size_t(params)) {
        e.half_width = y.size() == population ? 0.0 : std::numeric_limits<double>::infinity();
        return e;
    }
    double ss = 0;
    for (size_t i = 0; i < y.size(); ++i) {
        const double r = y[i] - b1 * x1[i] - b2 * x2[i];
        ss += r * r;
    }
    const double N = double(population);
    const double fpc = N > 0 ? std::max(0.0, 1.0 - n / N) : 1.0;
    const double variance = N * N * fpc * ss / (n - params) / n;
    e.half_width = student_t_quantile(0.5 + confidence / 2.0, n - params) * std::sqrt(variance);
    return e;
}

Estimate combined_ratio_estimate(const std::vector<RatioStratum>& strata, double confidence) {
    Estimate e;
    e.confidence = confidence;
    double ny = 0, nx = 0;  // N_h-weighted sums of the strata's means
    uint64_t df = 0;
    for (const RatioStratum& s : strata) {
        if (s.y.size() != s.x.size())
            throw std::invalid_argument("combined_ratio_estimate: y and x differ in size");
        e.units += s.y.size();
        e.population += s.population;
        if (s.y.empty()) continue;
        double sy = 0, sx = 0;
        for (size_t i = 0; i < s.y.size(); ++i) {
            sy += s.y[i];
            sx += s.x[i];
        }
        const double n = double(s.y.size());
        ny += double(s.population) * sy / n;
        nx += double(s.population) * sx / n;
        if (s.y.size() >= 2) df += s.y.size() - 1;
    }
    if (nx == 0.0) {
        e.half_width = std::numeric_limits<double>::infinity();
        return e;
    }
    e.value = ny / nx;
    if (df == 0) {
        e.half_width = e.units == e.population ? 0.0 : std::numeric_limits<double>::infinity();
        return e;
    }
    double variance = 0;  // of sum_h N_h mean(y_h - R x_h), then divided by X^2
    for (const RatioStratum& s : strata) {
        if (s.y.size() < 2) continue;
        const double n = double(s.y.size());
        double ss = 0, mean_d = 0;
        for (size_t i = 0; i < s.y.size(); ++i) mean_d += s.y[i] - e.value * s.x[i];
        mean_d /= n;
        for (size_t i = 0; i < s.y.size(); ++i) {
            const double d = s.y[i] - e.value * s.x[i] - mean_d;
            ss += d * d;
        }
        const double N = double(s.population);
        const double fpc = N > 0 ? std::max(0.0, 1.0 - n / N) : 1.0;
        variance += N * N * fpc * ss / (n - 1.0) / n;
    }
    variance /= nx * nx;
    e.half_width = student_t_quantile(0.5 + confidence / 2.0, double(df)) * std::sqrt(variance);
    return e;
}

}  // namespace rtsim
