#include "sim/sampling/estimators.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>

namespace rtsim {

namespace {

// Informative units (where some auxiliary is not zero) per auxiliary beyond the first. Counted
// over every measured unit, rayless ones included, 10 per auxiliary let a 1-in-100 sample of a
// sparse frame (a 1080p camel diffuse frame: 5 of 81 measured units with rays) fit all of them
// through its few units, residuals near zero, intervals that held the full run's cycles 30 times
// in 60; over informative units, 4 per auxiliary: 57 in 60 and no larger errors
// (docs/sampling.md). Each auxiliary beyond the first must also be non-zero in this many measured
// units: a 1-in-50 sample of a 1024x768 fandisk diffuse frame held one unit with node steps among
// 16 of background rays, and the fit through it estimated the frame's cycles -88% off at
// +-0.0%.
constexpr size_t kMinRegressionUnits = 4;
// Residual degrees of freedom below which a fit with every residual 0 (and y not 0 everywhere)
// is taken as showing no spread rather than an identity of the counter: box operations are the
// node steps in every unit, and a paired design's counters are its reference's where the two
// designs agree (the reference against itself gives its full run's totals exactly), so exact
// fits over a few units are identities. The fit that showed no spread though it could not (one
// unit alone carrying an auxiliary) is ruled out by the admission rules above.
constexpr size_t kExactFitDegrees = 2;

// Solves the p x p system m x = v (row-major m) by Gaussian elimination with partial pivoting,
// overwriting m and v; false when it is (nearly) singular. Regression fits have p of 6 or fewer.
bool solve_in_place(std::vector<double>& m, std::vector<double>& v, std::vector<double>& x) {
    const size_t p = v.size();
    double scale = 0;
    for (double a : m) scale = std::max(scale, std::fabs(a));
    for (size_t c = 0; c < p; ++c) {
        size_t best = c;
        for (size_t r = c + 1; r < p; ++r)
            if (std::fabs(m[r * p + c]) > std::fabs(m[best * p + c])) best = r;
        if (!(std::fabs(m[best * p + c]) > 1e-12 * scale)) return false;
        if (best != c) {
            for (size_t k = 0; k < p; ++k) std::swap(m[c * p + k], m[best * p + k]);
            std::swap(v[c], v[best]);
        }
        for (size_t r = c + 1; r < p; ++r) {
            const double f = m[r * p + c] / m[c * p + c];
            for (size_t k = c; k < p; ++k) m[r * p + k] -= f * m[c * p + k];
            v[r] -= f * v[c];
        }
    }
    x.assign(p, 0.0);
    for (size_t c = p; c-- > 0;) {
        double s = v[c];
        for (size_t k = c + 1; k < p; ++k) s -= m[c * p + k] * x[k];
        x[c] = s / m[c * p + c];
    }
    return true;
}

// m += w x x' for x of k entries (row-major k x k), each entry as (w x_j) x_k; restrict lets the
// compiler keep x in registers while it writes m.
void add_outer_product(double* __restrict m, const double* __restrict x, double w, size_t k) {
    for (size_t a = 0; a < k; ++a) {
        const double wx = w * x[a];
        for (size_t c = 0; c < k; ++c) m[a * k + c] += wx * x[c];
    }
}

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

bool solve_small(std::vector<double> m, std::vector<double> v, std::vector<double>& x) {
    return solve_in_place(m, v, x);
}

double student_t_cdf(double t, double df) {
    const double x = df / (df + t * t);
    const double tail = 0.5 * regularized_incomplete_beta(df / 2.0, 0.5, x);
    return t >= 0 ? 1.0 - tail : tail;
}

double student_t_quantile(double p, double df) {
    if (!(p > 0.0 && p < 1.0) || !(df >= 1.0))
        throw std::invalid_argument("student_t_quantile: p in (0, 1) and df >= 1");
    if (p == 0.5) return 0.0;
    // A sampled run asks for the same quantile for each of its hundreds of counters, and each
    // bisection costs a few hundred incomplete beta functions (5% of a 1-in-100 run).
    struct Known {
        double p, df, t;
    };
    thread_local std::vector<Known> known;
    for (const Known& k : known)
        if (k.p == p && k.df == df) return k.t;
    // Bisection on the CDF: monotone and safe; 200 halvings reach double precision.
    double lo = 0.0, hi = 1.0;
    const double target = p > 0.5 ? p : 1.0 - p;
    while (student_t_cdf(hi, df) < target) hi *= 2.0;
    for (int i = 0; i < 200 && hi - lo > 1e-14 * hi; ++i) {
        const double mid = 0.5 * (lo + hi);
        (student_t_cdf(mid, df) < target ? lo : hi) = mid;
    }
    const double t = 0.5 * (lo + hi);
    if (known.size() >= 16) known.erase(known.begin());
    known.push_back({p, df, p > 0.5 ? t : -t});
    return known.back().t;
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

RegressionDesign::RegressionDesign(const std::vector<Auxiliary>& aux, uint64_t population,
                                   const std::vector<double>* expansion)
    : population_(population) {
    if (aux.empty()) throw std::invalid_argument("regression_total: no auxiliary");
    n_ = aux[0].x.size();
    for (const Auxiliary& a : aux)
        if (a.x.size() != n_)
            throw std::invalid_argument("regression_total: the auxiliaries differ in size");
    const size_t k_all = aux.size();
    // The ratio estimator's variance model: residual variance proportional to x_0 (with one
    // auxiliary the fit is sum(y) / sum(x_0)).
    // Units where every auxiliary is zero (tiles without rays) add nothing to the fit: they
    // count for neither the auxiliaries admitted nor the degrees of freedom.
    for (size_t i = 0; i < n_; ++i)
        informative_ +=
            std::any_of(aux.begin(), aux.end(), [&](const Auxiliary& a) { return a.x[i] != 0; });
    if (expansion && expansion->size() != n_)
        throw std::invalid_argument("regression_total: a design weight per unit");
    unequal_ = expansion != nullptr;
    model_weight_.resize(n_);
    expansion_.assign(n_, n_ ? double(population_) / double(n_) : 1.0);
    for (size_t i = 0; i < n_; ++i) model_weight_[i] = aux[0].x[i] > 0 ? 1.0 / aux[0].x[i] : 1.0;
    weight_ = model_weight_;
    if (unequal_)
        for (size_t i = 0; i < n_; ++i) {
            expansion_[i] = (*expansion)[i];
            weight_[i] *= expansion_[i];
        }
    // Weighted normal equations over every auxiliary (full, symmetric), unit by unit with each
    // unit's auxiliaries in hand (a sweep over the columns per entry reloaded each one).
    std::vector<double> m(k_all * k_all, 0.0), row(k_all);
    for (size_t i = 0; i < n_; ++i) {
        for (size_t j = 0; j < k_all; ++j) row[j] = aux[j].x[i];
        add_outer_product(m.data(), row.data(), weight_[i], k_all);
    }
    // The normal equations of the auxiliaries in `set`.
    auto block = [&](const std::vector<size_t>& set, std::vector<double>& ms) {
        const size_t p = set.size();
        ms.resize(p * p);
        for (size_t a = 0; a < p; ++a)
            for (size_t c = 0; c < p; ++c) ms[a * p + c] = m[set[a] * k_all + set[c]];
    };
    // Auxiliaries are added in order; one whose part not explained by those already fitted (the
    // Schur complement of their block) is (nearly) zero adds nothing and is left out.
    std::vector<double> mf, z;
    for (size_t j = 0; j < k_all; ++j) {
        const double diag = m[j * k_all + j];
        const size_t nonzero = size_t(
            std::count_if(aux[j].x.begin(), aux[j].x.end(), [](double x) { return x != 0; }));
        if (j > 0 &&
            (informative_ < kMinRegressionUnits * j || nonzero < kMinRegressionUnits || diag <= 0))
            continue;
        double pivot = diag;
        if (!fitted_.empty()) {
            block(fitted_, mf);
            std::vector<double> cross(fitted_.size());
            for (size_t a = 0; a < fitted_.size(); ++a) cross[a] = m[fitted_[a] * k_all + j];
            solve_small(mf, cross, z);
            for (size_t a = 0; a < fitted_.size(); ++a) pivot -= cross[a] * z[a];
        }
        if (!(pivot > 1e-9 * diag)) {
            if (j == 0) break;
            continue;
        }
        fitted_.push_back(j);
    }
    if (fitted_.empty()) return;  // the first auxiliary is zero in every unit
    // The total is sum_i h_i y_i with h_i = X' M^-1 x_i w_i; g_i = h_i n / N is unit i's weight
    // against the plain expansion's (Deville & Sarndal 1992: calibration weights). An auxiliary
    // nearly spanned by the others in the sample but not in the population (a sample of
    // background units, whose work is twice their node steps, among few object units) makes the
    // fit extrapolate, with weights far from 1: a 1-in-100 sample of a 1080p camel frame of
    // primary rays had g from -355 to 152 and estimated a negative total of cycles with a +-0.1%
    // interval. Auxiliaries are dropped from the last until every |g_i - 1| <= kMaxWeightShift
    // (bounded calibration; the ratio estimator, one auxiliary, is always kept). Sound fits stay
    // well inside it: g within [0.5, 2.6] on 1080p bunny and camel frames at 1 in 10, [-2.6, 4.6]
    // on the synthetic population of tests/sim/test_sampling.cpp.
    constexpr double kMaxWeightShift = 10.0;
    while (fitted_.size() > 1) {
        block(fitted_, mf);
        std::vector<double> totals(fitted_.size());
        for (size_t a = 0; a < fitted_.size(); ++a) totals[a] = aux[fitted_[a]].total;
        std::vector<double> lambda;  // M^-1 X
        bool wild = !solve_small(mf, totals, lambda);
        for (size_t i = 0; i < n_ && !wild; ++i) {
            double h = 0;
            for (size_t a = 0; a < fitted_.size(); ++a) h += lambda[a] * aux[fitted_[a]].x[i];
            const double g = h * weight_[i] / expansion_[i];
            wild = !(std::fabs(g - 1.0) <= kMaxWeightShift);
        }
        if (!wild) break;
        fitted_.pop_back();
    }
    // A unit with a leverage of 1 is the fit's only unit in some direction: its residual is 0
    // whatever it measured, and the interval would show none of its spread. The auxiliary that
    // puts it there goes, last first (the ratio estimator stays).
    while (true) {
        design_fitted(aux);
        if (!singular_ || fitted_.size() <= 1) break;
        fitted_.pop_back();
    }
}

void RegressionDesign::design_fitted(const std::vector<Auxiliary>& aux) {
    // The fitted auxiliaries: their values unit by unit, totals and normal equations.
    const size_t p = fitted_.size();
    singular_ = false;
    moved_weight_.clear();
    one_less_leverage_.clear();
    model_factor_ = 0;
    x_.resize(n_ * p);
    for (size_t i = 0; i < n_; ++i)
        for (size_t a = 0; a < p; ++a) x_[i * p + a] = aux[fitted_[a]].x[i];
    totals_.resize(p);
    for (size_t a = 0; a < p; ++a) totals_[a] = aux[fitted_[a]].total;
    normal_.assign(p * p, 0.0);
    for (size_t i = 0; i < n_; ++i) add_outer_product(normal_.data(), &x_[i * p], weight_[i], p);
    const double n = double(n_), N = double(population_);
    fpc_ = N > 0 ? std::max(0.0, 1.0 - n / N) : 1.0;
    if (informative_ <= p || fpc_ == 0) return;
    // Each left-out fit in closed form (Sherman-Morrison; Cook and Weisberg 1982, 2.2): with
    // M the weighted normal matrix, unit i of weight w, auxiliaries x_i and residual r_i,
    // b_(i) = b - M^-1 x_i w r_i / (1 - h_i), h_i = w x_i' M^-1 x_i its leverage, so the
    // total moves by (X' M^-1 x_i) w r_i / (1 - h_i): O(p^2) a unit instead of a p x p solve
    // (which was 12-18% of a 1-in-20 or 1-in-50 run's host time, 222 counters x 162-405 units).
    // Everything but r_i is the design's: computed here once for every y regressed on it.
    // h_i = 1: the fit cannot do without unit i (the only one where an auxiliary moves).
    std::vector<double> inverse(p * p), unit_vector(p), column;
    for (size_t c = 0; c < p; ++c) {
        std::fill(unit_vector.begin(), unit_vector.end(), 0.0);
        unit_vector[c] = 1.0;
        solve_small(normal_, unit_vector, column);
        for (size_t a = 0; a < p; ++a) inverse[a * p + c] = column[a];
    }
    std::vector<double> lambda(p, 0.0);  // M^-1 X
    for (size_t a = 0; a < p; ++a)
        for (size_t c = 0; c < p; ++c) lambda[a] += inverse[a * p + c] * totals_[c];
    moved_weight_.resize(n_);
    one_less_leverage_.resize(n_);
    for (size_t i = 0; i < n_ && !singular_; ++i) {
        const double* xi = &x_[i * p];
        double moved = 0, leverage = 0;
        for (size_t a = 0; a < p; ++a) moved += lambda[a] * xi[a];
        for (size_t a = 0; a < p; ++a) {
            double u = 0;
            for (size_t c = 0; c < p; ++c) u += inverse[a * p + c] * xi[c];
            leverage += xi[a] * u;
        }
        leverage *= weight_[i];
        singular_ = !(1.0 - leverage > 1e-10);
        moved_weight_[i] = moved * weight_[i];
        one_less_leverage_[i] = 1.0 - leverage;
    }
    // The fit's own model's prediction variance of the total (Royall 1970; Valliant, Dorfman
    // and Royall 2000, 4.2), over sigma^2: the units not measured, sum x_0 of them, plus the
    // coefficients' uncertainty carried to those units' auxiliaries, X_out' M^-1 X_out.
    std::vector<double> outside(totals_);  // X_out: the totals less the measured units' sums
    for (size_t i = 0; i < n_; ++i)
        for (size_t a = 0; a < p; ++a) outside[a] -= x_[i * p + a];
    // The model's normal equations weigh units by the model's variance alone (the design
    // weights are the design's, not the model's).
    std::vector<double> model_inverse = inverse;
    if (unequal_) {
        std::vector<double> model_normal(p * p, 0.0);
        for (size_t i = 0; i < n_; ++i)
            add_outer_product(model_normal.data(), &x_[i * p], model_weight_[i], p);
        for (size_t c = 0; c < p; ++c) {
            std::fill(unit_vector.begin(), unit_vector.end(), 0.0);
            unit_vector[c] = 1.0;
            solve_small(model_normal, unit_vector, column);
            for (size_t a = 0; a < p; ++a) model_inverse[a * p + c] = column[a];
        }
    }
    double spread = 0;
    for (size_t a = 0; a < p; ++a)
        for (size_t c = 0; c < p; ++c) spread += outside[a] * model_inverse[a * p + c] * outside[c];
    // fitted_[0] is auxiliary 0, the variance model's x_0.
    model_factor_ = std::max(0.0, outside[0]) + std::max(0.0, spread);
}

Estimate RegressionDesign::total(const std::vector<double>& y, double confidence) const {
    if (y.size() != n_)
        throw std::invalid_argument("regression_total: y and an auxiliary differ in size");
    Estimate e;
    e.confidence = confidence;
    e.units = n_;
    e.population = population_;
    if (fitted_.empty()) {
        e.half_width = std::numeric_limits<double>::infinity();
        return e;
    }
    const size_t p = fitted_.size();
    std::vector<double> v(p, 0.0), coef;
    for (size_t i = 0; i < n_; ++i) {
        const double w = weight_[i];
        for (size_t a = 0; a < p; ++a) v[a] += w * x_[i * p + a] * y[i];
    }
    solve_small(normal_, v, coef);
    for (size_t a = 0; a < p; ++a) e.value += coef[a] * totals_[a];
    if (fpc_ == 0) return e;  // every unit measured: the total is known, the interval empty
    if (informative_ <= p) {  // no residual degree of freedom
        e.half_width = std::numeric_limits<double>::infinity();
        return e;
    }
    // The variance by the delete-one jackknife of the total (Sarndal et al. 1992, 11.5): each
    // unit left out in turn, the fit redone (in closed form: the design's constructor). The
    // residuals' formula, N^2 (1 - n/N) s_e^2 / n, reads a unit of high leverage (one of a few
    // heavy units) through its small fitted residual and was too narrow: on a 1080p camel frame
    // of primary rays, 1 unit in 10, its 95% intervals held the full run's cycles in 80% of 200
    // samples, the jackknife's in 92% (bunny: 92% and 94%).
    const double n = double(n_), N = double(population_);
    std::vector<double> residual(n_);
    for (size_t i = 0; i < n_; ++i) {
        double fitted_y = 0;
        for (size_t a = 0; a < p; ++a) fitted_y += coef[a] * x_[i * p + a];
        residual[i] = y[i] - fitted_y;
    }
    // Every residual 0 on few degrees of freedom while y moved: the fit shows no spread, which
    // says nothing of the units not measured (a sample whose object units all fall in a few
    // strata fits them exactly). Many units fitting exactly are an identity of the counter.
    double y_scale = 0, r_scale = 0;
    for (size_t i = 0; i < n_; ++i) {
        y_scale = std::max(y_scale, std::fabs(y[i]));
        r_scale = std::max(r_scale, std::fabs(residual[i]));
    }
    if (y_scale > 0 && r_scale <= 1e-9 * y_scale && informative_ - p < kExactFitDegrees) {
        e.half_width = std::numeric_limits<double>::infinity();
        e.caveat = fmt::format(
            "the {} informative measured units fit the model exactly: no spread to estimate "
            "from; measure more units",
            informative_);
        return e;
    }
    double variance = 0;
    if (!singular_) {
        std::vector<double> replicate(n_);
        double mean = 0;
        for (size_t i = 0; i < n_; ++i) {
            replicate[i] = e.value - moved_weight_[i] * residual[i] / one_less_leverage_[i];
            mean += replicate[i];
        }
        mean /= n;
        for (double t : replicate) variance += (t - mean) * (t - mean);
        variance *= fpc_ * (n - 1.0) / n;
        e.replicates = std::move(replicate);
    } else {
        // A unit the fit cannot do without (the only one where an auxiliary moves): the
        // residuals' formula.
        double ss = 0;
        for (double r : residual) ss += r * r;
        variance = N * N * fpc_ * ss / (n - double(p)) / n;
    }
    // With few degrees of freedom, at least the fit's model's variance, sigma^2 estimated from
    // the residuals. The jackknife is then itself a noisy estimate, and too small where the
    // estimate is off: over 300 seeds of a 1080p elephant frame of AO rays, paired, 1 in 50 (7-8
    // informative units), its half-widths spread 0.27-14.8% of the cycles about errors of
    // standard deviation 0.57%, and held the full run's cycles in 90.0% of them; the model's
    // variance knows the reference's cycles of every unit left out, and the larger of the two
    // held them in 94.3%, 4% wider on average (docs/sampling.md). With many
    // units the jackknife is reliable and, unlike the model's, right where the model is not
    // (a trend the fit through the origin misses): it stands alone there.
    if (informative_ - p < kModelFloorDegrees) {
        double residual_ss = 0;
        for (size_t i = 0; i < n_; ++i) residual_ss += model_weight_[i] * residual[i] * residual[i];
        variance = std::max(variance, residual_ss / double(informative_ - p) * model_factor_);
    }
    e.t_quantile = student_t_quantile(0.5 + confidence / 2.0, double(informative_ - p));
    e.half_width = e.t_quantile * std::sqrt(variance);
    return e;
}

Estimate regression_total(const std::vector<double>& y, const std::vector<Auxiliary>& aux,
                          uint64_t population, double confidence) {
    return RegressionDesign(aux, population).total(y, confidence);
}

void JointEstimates::add(const std::string& name, Estimate e) {
    if (!e.replicates.empty() && e.replicates.size() != units_)
        throw std::invalid_argument("JointEstimates: " + name + " has " +
                                    std::to_string(e.replicates.size()) + " replicates, not " +
                                    std::to_string(units_));
    totals_[name] = std::move(e);
}

const Estimate* JointEstimates::find(const std::string& name) const {
    const auto it = totals_.find(name);
    return it == totals_.end() ? nullptr : &it->second;
}

bool JointEstimates::calibrate(const std::vector<std::string>& names, double known) {
    std::vector<Estimate*> group;
    for (const std::string& n : names) {
        const auto it = totals_.find(n);
        if (it == totals_.end()) continue;  // never moved in a measured unit: 0
        if (it->second.replicates.size() != units_ || !std::isfinite(it->second.half_width))
            return false;
        group.push_back(&it->second);
    }
    double sum = 0;
    for (const Estimate* e : group) sum += e->value;
    if (group.empty() || !(sum > 0)) return false;
    std::vector<double> replicate_sums(units_, 0.0);
    for (size_t i = 0; i < units_; ++i) {
        for (const Estimate* e : group) replicate_sums[i] += e->replicates[i];
        if (!(replicate_sums[i] > 0)) return false;
    }
    for (size_t i = 0; i < units_; ++i)
        for (Estimate* e : group) e->replicates[i] *= known / replicate_sums[i];
    for (Estimate* e : group) {
        e->value *= known / sum;
        e->half_width = e->t_quantile * std::sqrt(jackknife_variance(e->replicates));
    }
    return true;
}

double JointEstimates::jackknife_variance(const std::vector<double>& r) const {
    if (r.empty()) return 0.0;
    const double n = double(r.size()), N = double(population_);
    const double fpc = N > 0 ? std::max(0.0, 1.0 - n / N) : 1.0;
    double mean = 0;
    for (double t : r) mean += t;
    mean /= n;
    double ss = 0;
    for (double t : r) ss += (t - mean) * (t - mean);
    return fpc * (n - 1.0) / n * ss;  // as regression_total's
}

Estimate JointEstimates::of(const std::function<double(const Lookup&)>& f,
                            double confidence) const {
    return of_many([&](const Lookup& total) { return std::vector<double>{f(total)}; }, confidence)
        .front();
}

std::vector<Estimate> JointEstimates::of_many(
    const std::function<std::vector<double>(const Lookup&)>& f, double confidence) const {
    std::map<std::string, const Estimate*> used;
    const std::vector<double> values = f([&](const std::string& name) {
        const auto it = totals_.find(name);
        if (it == totals_.end()) return 0.0;
        used[name] = &it->second;
        return it->second.value;
    });
    const size_t k = values.size();
    double t = 0;
    bool infinite = false;
    for (const auto& [name, est] : used) {
        (void)name;
        t = std::max(t, est->t_quantile);
        infinite = infinite || std::isinf(est->half_width);
    }
    // Each unit left out of every total at once.
    std::vector<double> variance(k, 0.0);
    if (std::any_of(used.begin(), used.end(),
                    [](const auto& u) { return !u.second->replicates.empty(); })) {
        std::vector<std::vector<double>> replicates(k, std::vector<double>(units_));
        for (size_t i = 0; i < units_; ++i) {
            const std::vector<double> r = f([&](const std::string& name) {
                const auto it = used.find(name);
                if (it == used.end()) return 0.0;
                return it->second->replicates.empty() ? it->second->value
                                                      : it->second->replicates[i];
            });
            for (size_t j = 0; j < k; ++j) replicates[j][i] = r[j];
        }
        for (size_t j = 0; j < k; ++j) variance[j] = jackknife_variance(replicates[j]);
    }
    // What a total's interval holds beyond its jackknife, through f's slope in it.
    for (const auto& [name, est] : used) {
        if (est->t_quantile <= 0 || std::isinf(est->half_width)) continue;
        const double own = est->half_width / est->t_quantile;
        const double extra = own * own - jackknife_variance(est->replicates);
        if (!(extra > 1e-12 * own * own)) continue;
        const double step = 1e-6 * std::max(std::fabs(est->value), 1.0);
        const std::vector<double> moved = f([&, n = name](const std::string& asked) {
            const auto it = used.find(asked);
            if (it == used.end()) return 0.0;
            return it->second->value + (asked == n ? step : 0.0);
        });
        for (size_t j = 0; j < k; ++j) {
            const double slope = (moved[j] - values[j]) / step;
            variance[j] += slope * slope * extra;
        }
    }
    std::vector<Estimate> out(k);
    for (size_t j = 0; j < k; ++j) {
        Estimate& e = out[j];
        e.confidence = confidence;
        e.units = units_;
        e.population = population_;
        e.value = values[j];
        e.t_quantile = infinite ? 0.0 : t;
        e.half_width =
            infinite ? std::numeric_limits<double>::infinity() : t * std::sqrt(variance[j]);
    }
    return out;
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
