#include "sim/sampling.h"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace rtsim {

namespace {

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

}  // namespace rtsim
