"""A drift prediction's standard error when the residuals are correlated in time.

A drift record read every minute for hours carries errors that last for many readings (air
currents, a sensor's own warm-up, heat flows no feature follows). Counting its readings as
independent made the standard errors of forward predictions 20 to 60 times smaller than their
errors. Two oracles here, each computed in the test:

* the independent truth machine (tests/truth) with AR(1) noise written here (seeded): the later
  6 h, predicted from the first 10 h, must fall within 2 standard errors about 95 % of the time;
* the formulas themselves: the lag-1 autocorrelation of a series written here, and the covariance
  the model file carries, rebuilt from the fit's posterior by hand.
"""
import numpy as np

from truth import SpindleSchedule, TruthMachine, campaigns, random_effect
from truth.campaigns import write_csv

from mtcomp.identification.predict import predict_readings
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements
from mtcomp.thermal import diagnose_thermal

SCHEDULE = SpindleSchedule(((0.0, 0.0), (1800.0, 2000.0), (5400.0, 6000.0), (12600.0, 0.0),
                            (16200.0, 4000.0), (21600.0, 0.0), (43200.0, 5000.0), (50400.0, 0.0)))
INTERVAL_S = 60.0
#: the correlated error: AR(1) with this time constant and marginal standard deviation
AR_TAU_S, AR_SD_UM = 1200.0, 0.3


def _ar1(rng, n, phi, sd):
    """n samples of a stationary AR(1) series x_i = phi x_(i-1) + e_i of marginal sd ``sd``."""
    x = np.empty(n)
    x[0] = rng.normal(0.0, sd)
    e = rng.normal(0.0, sd * np.sqrt(1.0 - phi ** 2), n)
    for i in range(1, n):
        x[i] = phi * x[i - 1] + e[i]
    return x


def _record_with_correlated_noise(path, rng, driver):
    """A 16 h record of the truth machine with a hidden drift, white noise 0.05 um and AR(1) noise."""
    eff = random_effect("thermal_drift", TruthMachine("xfyz"), rng, driver=driver, schedule=SCHEDULE)
    truth = TruthMachine.random("xfyz", rng, effects=(eff,))
    res = campaigns.thermal(truth, path, rng, duration_h=16.0, interval_s=INTERVAL_S, schedule=SCHEDULE,
                            noise_um=0.05)
    cols = dict(res.columns)
    phi = np.exp(-INTERVAL_S / AR_TAU_S)
    for c in "xyz":
        v = np.asarray(cols[f"disp_{c}_um"], dtype=float)
        cols[f"disp_{c}_um"] = v + _ar1(rng, len(v), phi, AR_SD_UM)
    write_csv(path, cols)
    lines = path.read_text().splitlines()
    t = np.asarray(cols["t_s"], dtype=float)
    s = int(np.searchsorted(t, 10 * 3600.0))
    fit, later = path.with_name("fit.csv"), path.with_name("later.csv")
    fit.write_text("\n".join(lines[:1 + s]) + "\n")
    later.write_text("\n".join([lines[0]] + lines[1 + s:]) + "\n")
    return fit, later


def test_two_standard_errors_cover_the_later_readings_of_a_record_with_correlated_noise(tmp_path):
    """Four records (drivers temperature, spindle, temperature, time), seeded: the z-scores of the
    later 6 h (3 channels, 361 readings each) have an rms near 1 and 2 standard errors cover about
    95 % of them (1.04 and 94.6 % when written). Counting 600 correlated readings as independent,
    the z-scores had an rms of 26 and 2 standard errors covered 8 %."""
    machine = load_machine("xfyz")
    z = []
    for seed, driver in zip(range(4), ("temperature", "spindle", "temperature", "time")):
        folder = tmp_path / f"r{seed}"
        folder.mkdir()
        fit, later = _record_with_correlated_noise(folder / "record.csv", np.random.default_rng(40 + seed),
                                                   driver)
        d = diagnose_thermal(machine, read_measurements(fit))
        data = read_measurements(later)
        cols = predict_readings(d.model, data).columns
        for c in "xyz":
            err = cols[f"pred_disp_{c}_um"] - data.channels[c] * 1e3
            z.append(err / cols[f"pred_disp_{c}_um_sd"])
    z = np.concatenate(z)
    assert np.all(np.isfinite(z))
    coverage = float(np.mean(np.abs(z) <= 2.0))
    ratio = float(np.sqrt(np.mean(z ** 2)))
    print(f"\nAR(1) noise {AR_SD_UM} um, tau {AR_TAU_S:g} s: rms z {ratio:.2f}, 2 sd cover {coverage:.1%}")
    assert 0.85 <= coverage <= 0.99
    assert 0.5 <= ratio <= 1.5


def test_the_lag_one_autocorrelation_is_that_of_the_series():
    """An AR(1) series with phi 0.9 has lag-1 autocorrelation 0.9 (within its sampling error,
    about sqrt((1 - phi^2) / n) = 0.004 for n = 20000); white noise has 0; a series that alternates
    in sign is counted as independent (clipped at 0)."""
    from mtcomp.thermal._fit import residual_autocorrelation
    rng = np.random.default_rng(3)
    n = 20000
    series = np.column_stack([_ar1(rng, n, 0.9, 1.0), rng.normal(0.0, 1.0, n),
                              np.where(np.arange(n) % 2, 1.0, -1.0) + rng.normal(0.0, 0.1, n)])
    rho = residual_autocorrelation(series)
    np.testing.assert_allclose(rho[:2], [0.9, 0.0], rtol=0, atol=0.015)
    assert rho[2] == 0.0


def test_the_model_files_covariance_is_the_posterior_scaled_for_correlation_plus_the_model_error(tmp_path):
    """The covariance a thermal model carries, rebuilt here: each channel's posterior (coefficients,
    intercept) times (1 + rho) / (1 - rho), rho the lag-1 sample autocorrelation of its residuals
    computed here with numpy's correlate, and the square of its forward-validated rms added to the intercept's
    variance. So a prediction's variance is its parameter share plus that square."""
    fit_path, _ = _record_with_correlated_noise(tmp_path / "record.csv", np.random.default_rng(9),
                                                "temperature")
    d = diagnose_thermal(load_machine("xfyz"), read_measurements(fit_path))
    fit = d.thermal
    resid = fit.measured_um - fit.fitted_um
    for j, ch in enumerate(fit.channels):
        r = resid[:, j] - resid[:, j].mean()
        acov = np.correlate(r, r, mode="full")[len(r) - 1:]
        rho = acov[1] / acov[0]             # the sample autocorrelation (Box and Jenkins 1976)
        want = fit.results[j].covariance * 1e6 * (1 + rho) / (1 - rho)
        want[-1, -1] += fit.chosen.forward_rms_um[j] ** 2
        np.testing.assert_allclose(fit.covariance[j], want, rtol=2e-3, atol=0)
        assert rho > 0.6                   # AR(1) of 20 min read every minute, less what the fit takes
    # the model file's covariance is the same, in mm^2
    u = d.model.uncertainty
    names = list(u["names"])
    for j, ch in enumerate(fit.channels):
        block = [names.index(f"TD_{ch.upper()}_{f}") for f in fit.chosen.features] + \
            [names.index(f"TD_{ch.upper()}_zero")]
        np.testing.assert_allclose(np.asarray(u["covariance"])[np.ix_(block, block)] * 1e6,
                                   fit.covariance[j], rtol=1e-12, atol=0)


def test_forward_covariance_by_hand():
    from mtcomp.thermal._fit import forward_covariance
    cov = np.array([[[4.0, 1.0], [1.0, 2.0]]])
    out = forward_covariance(cov, np.array([0.5]), np.array([3.0]))
    np.testing.assert_allclose(out[0], [[12.0, 3.0], [3.0, 15.0]], rtol=1e-15, atol=0)
    assert cov[0, 1, 1] == 2.0             # the posterior it was given is left as it was
