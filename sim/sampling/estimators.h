// Confidence intervals for figures estimated from a sample of a run's work (sampled
// simulation): a frame's rays are cut into N units of consecutive rays, n of them are simulated in
// detail, and every figure of the whole run is estimated from them with a confidence interval.
//
// The estimators are the survey-sampling ones (Cochran, Sampling Techniques, 1977, ch. 2 and 6):
// a mean of n units drawn without replacement from N, with the finite-population correction
// (1 - n/N) on its variance; and a ratio sum(y)/sum(x) (cycles per ray when units hold
// different numbers of rays, bytes per ray, a hit rate as hits per access), whose variance comes
// from the residuals y - R x (the delta method). Intervals use Student's t with n - 1 degrees of
// freedom. SMARTS (Wunderlich et al., ISCA 2003) applies the same estimator to systematic
// samples of an instruction stream.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace rtsim {

// The p-quantile of Student's t distribution with `df` degrees of freedom (df >= 1, 0 < p < 1).
double student_t_quantile(double p, double df);

// Its CDF, from the regularised incomplete beta function (exposed for tests).
double student_t_cdf(double t, double df);

struct Estimate {
    double value = 0;         // the estimate
    double half_width = 0;    // of the interval: value +- half_width
    double confidence = 0;    // nominal coverage, e.g. 0.95
    uint64_t units = 0;       // n: units measured
    uint64_t population = 0;  // N: units in the run
    double t_quantile = 0;    // Student's t the half-width used (0: an exact or infinite one)
    // The delete-one jackknife's replicates of `value` (unit i left out of the fit), when the
    // half-width came from them; empty otherwise.
    std::vector<double> replicates;
    // Why the interval cannot be trusted as printed (empty when it can): a fit with no spread
    // to show, an estimate that extrapolates. Reported beside the estimate in stats.json and
    // the summary; where the data support no width at all the half-width is infinite too.
    std::string caveat;
    double lo() const { return value - half_width; }
    double hi() const { return value + half_width; }
    // half_width / |value| (0 when the value is 0 and the interval empty; infinite when the
    // value is 0 and the interval is not).
    double relative_half_width() const;
};

// The mean of a unit figure over the population, from the measured units `x` (n >= 2 for an
// interval; with n == N the interval is empty: everything was measured).
Estimate mean_estimate(const std::vector<double>& x, uint64_t population, double confidence = 0.95);

// The population ratio sum(y) / sum(x) over all N units, from the measured units' pairs.
Estimate ratio_estimate(const std::vector<double>& y, const std::vector<double>& x,
                        uint64_t population, double confidence = 0.95);

// An auxiliary figure of a sample: its value in each measured unit and its population total
// (known for every unit, as a unit's rays and steps are known before timing).
struct Auxiliary {
    std::vector<double> x;
    double total = 0;
};

// Solves the p x p system m x = v (row-major m, p small) by Gaussian elimination with partial
// pivoting; false when it is (nearly) singular.
bool solve_small(std::vector<double> m, std::vector<double> v, std::vector<double>& x);

// Below this many residual degrees of freedom a regression total's variance is at least its fit's
// model's (regression_total). The jackknife's own relative standard error is about sqrt(2 / df):
// 32% at 20, where Student's t (2.09) is near the normal's 1.96; the sparse frames that need the
// floor have 3-10 (1080p camel and elephant frames of AO, diffuse and path rays, 1 in 50), dense
// ones 76-157.
constexpr size_t kModelFloorDegrees = 20;

// The population total of y from n of N units by regression through the origin on auxiliary
// figures whose population totals are known (Cochran 1977, ch. 7; Sarndal et al. 1992, the GREG
// estimator): y ~ sum_k b_k x_k fitted on the measured units by least squares weighted for a
// residual variance proportional to the first auxiliary (the ratio estimator's model), total =
// sum_k b_k X_k, its variance by the delete-one jackknife of that total with the finite-
// population correction (1 - n/N) (the residuals' N^2 (1 - n/N) s_e^2 / n when leaving out a unit
// leaves the fit singular) or, with fewer than 20 residual degrees of freedom, the fit's model's
// prediction variance of the total where that is larger, s^2 (sum of x_0 over the units not
// measured + X_out' M^-1 X_out) (Royall 1970: the jackknife on few units is itself noisy), t with
// m - p degrees of freedom for p auxiliaries fitted on m
// informative units (those where some auxiliary is not zero: a tile without rays informs no fit).
// The first auxiliary is always fitted; auxiliary k (k >= 1) only with at least 4 k informative
// units (fewer leave too few degrees of freedom per coefficient), and not when it is zero in every
// unit or (nearly) a combination of those before it. An auxiliary must also be non-zero in at
// least 4 measured units, and none may leave a unit with a leverage of 1 (the fit's only unit in
// some direction, whose residual is then 0 whatever its y): such an auxiliary is dropped, last
// first, down to the ratio estimator. With one auxiliary it is the ratio estimator's total.
// `value` is the total; the interval is infinite with m <= p, or with a caveat when y is not 0
// everywhere yet every residual is, on a single residual degree of freedom (a fit that shows no
// spread from so few units says nothing of the units not measured); it is empty when every unit
// was measured.
Estimate regression_total(const std::vector<double>& y, const std::vector<Auxiliary>& aux,
                          uint64_t population, double confidence = 0.95);

// regression_total in two steps: the fit's design (which auxiliaries are fitted, their normal
// equations, each unit's weight, leverage and pull on the total) depends on the auxiliaries
// alone, so a sample's many counters regressed on the same auxiliaries share one; total(y) is
// regression_total(y, aux, population, confidence), figure for figure.
class RegressionDesign {
  public:
    // `expansion`, when given: each measured unit's design weight, 1 / its chance of being
    // drawn (a stratum's size when one unit is drawn per stratum of unequal sizes), so the fit
    // weighs each unit by the units it stands for (the GREG estimator's design weights); the
    // model's variance keeps the fit's own weights. Without it every unit stands for N / n.
    RegressionDesign(const std::vector<Auxiliary>& aux, uint64_t population,
                     const std::vector<double>* expansion = nullptr);
    Estimate total(const std::vector<double>& y, double confidence = 0.95) const;

  private:
    // The design of the auxiliaries in fitted_: their values, totals, normal equations, each
    // unit's leverage and pull on the total, the model's variance factor.
    void design_fitted(const std::vector<Auxiliary>& aux);
    size_t n_ = 0;            // units measured
    size_t informative_ = 0;  // of them, where some auxiliary is not zero
    uint64_t population_ = 0;
    std::vector<size_t> fitted_;             // the auxiliaries fitted, in order
    std::vector<double> weight_;             // per unit: design weight / x_0 (x_0 = 0: 1)
    std::vector<double> model_weight_;       // per unit: 1 / x_0 (1 where x_0 is 0)
    std::vector<double> expansion_;          // per unit: its design weight (N / n: equal)
    bool unequal_ = false;                   // design weights given
    std::vector<double> x_;                  // per unit, the fitted auxiliaries (row-major)
    std::vector<double> totals_;             // the fitted auxiliaries' population totals
    std::vector<double> normal_;             // their weighted normal equations, p x p
    std::vector<double> moved_weight_;       // per unit: (X' M^-1 x_i) w_i
    std::vector<double> one_less_leverage_;  // per unit: 1 - h_i
    double fpc_ = 1;                         // 1 - n / N
    bool singular_ = false;                  // some unit's leverage is 1
    double model_factor_ = 0;  // the model's prediction variance of the total over sigma^2
};

// A stratum of a stratified sample: its measured units' pairs and how many units it has.
struct RatioStratum {
    std::vector<double> y, x;
    uint64_t population = 0;
};

// The combined ratio estimator over strata sampled at different rates (Cochran 1977, 6.11):
// R = sum_h N_h mean(y_h) / sum_h N_h mean(x_h), its variance from each stratum's residuals
// y - R x with that stratum's finite-population correction, t with sum(n_h - 1) degrees of
// freedom. With one stratum it is ratio_estimate. A stratum with fewer than 2 measured units
// borrows nothing and adds no variance: its units count at the ratio of the others.
Estimate combined_ratio_estimate(const std::vector<RatioStratum>& strata, double confidence = 0.95);

// Totals estimated from one sample (a run's counters and cycles), for figures that are functions
// of several of them: energy is a sum of counters times costs per event, power that over the
// cycles. A function's interval is the delete-one jackknife of the function itself (unit i left
// out of every total at once, so the totals' covariances count; Wolter 2007, 4.5), plus,
// independently, whatever width a total carries beyond its own jackknife (the rule of three's
// floor, the residuals' formula where leaving a unit out was singular), times the function's
// slope in it. t is the largest of the totals' (the fewest degrees of freedom).
class JointEstimates {
  public:
    using Lookup = std::function<double(const std::string&)>;
    JointEstimates() = default;
    // n units measured of N.
    JointEstimates(size_t units, uint64_t population) : units_(units), population_(population) {}
    void add(const std::string& name, Estimate e);
    bool empty() const { return totals_.empty(); }
    // The estimate added as `name`, or nullptr.
    const Estimate* find(const std::string& name) const;
    // Totals whose sum is known exactly (box operations summed over the units are the frame's
    // node steps): each total and each of its replicates scaled so that the totals sum to
    // `known`, half-widths from the scaled replicates. The split between them stays estimated;
    // their sum, and anything that depends on it alone, is then exact. False (nothing changed)
    // when a total has no replicates or they sum to zero.
    bool calibrate(const std::vector<std::string>& names, double known);
    // The estimate of f over the totals; a total f asks for that was not added counts 0 (a
    // counter that never moved in a measured unit).
    Estimate of(const std::function<double(const Lookup&)>& f, double confidence = 0.95) const;
    // The same for several functions at once (f returns their values, always as many).
    std::vector<Estimate> of_many(const std::function<std::vector<double>(const Lookup&)>& f,
                                  double confidence = 0.95) const;

  private:
    // The jackknife's variance of replicates r (0 with none).
    double jackknife_variance(const std::vector<double>& r) const;
    size_t units_ = 0;
    uint64_t population_ = 0;
    std::map<std::string, Estimate> totals_;
};

}  // namespace rtsim
