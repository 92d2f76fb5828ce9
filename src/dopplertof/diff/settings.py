"""The fit's default settings, in a module of their own: the command line's help shows
them without importing the fit (NumPy, the renderer)."""

#: default samples per pixel of the fit's renders
FIT_SPP = 256

#: the Jacobian's renders take this fraction of the residuals' samples (default):
#: Gauss-Newton needs the Jacobian only approximately, and the metric of two
#: independent Jacobians (:func:`dopplertof.diff.fit_covariance.metric`) is unbiased at any
#: sample count
JACOBIAN_SHARE = 0.25
