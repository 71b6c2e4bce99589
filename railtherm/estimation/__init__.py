"""The estimation: from records to an estimate of a structure's parameters.

- :mod:`~railtherm.estimation.models`: exact discretisation, simulation and sensitivities of
  any structure of :mod:`railtherm.structures`;
- :mod:`~railtherm.estimation.kvalue`: the standardised static method, k of eq. 10;
- :mod:`~railtherm.estimation.pem`: the paper's simulation-error prediction error method
  (eqs. 15-20): the fit, its starts and flags, with :mod:`~railtherm.estimation.solver`
  (Levenberg-Marquardt) and :mod:`~railtherm.estimation.hac` (the HAC covariance);
- :mod:`~railtherm.estimation.kalman`: the Kalman filter's maximum likelihood;
- :mod:`~railtherm.estimation.estimate`: the :class:`~railtherm.estimation.estimate.Estimate`
  both estimators return;
- :mod:`~railtherm.estimation.metrics`, :mod:`~railtherm.estimation.acf`,
  :mod:`~railtherm.estimation.diagnostics`: R² (eq. 21), RMSE, AIC, BIC, residual whiteness,
  model selection.
"""
