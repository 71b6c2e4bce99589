"""The study: the per-vehicle pipeline and what is built on its fits.

- :mod:`~railtherm.study.identify`: one vehicle's fit (clean windows -> k -> fit -> verdict),
  the systematic uncertainty budget, plausibility and the verdict (:mod:`~railtherm.study.quality`:
  the measures a fit file records, the verdict's rules);
- :mod:`~railtherm.study.run`: the same without the workflow (``railtherm fit``);
- :mod:`~railtherm.study.plan`: the files of a study, what each of the workflow's rules reads
  and writes;
- :mod:`~railtherm.study.fit`: a written fit read back as a model to simulate;
- :mod:`~railtherm.study.aggregate`, :mod:`~railtherm.study.smallsample`: class statistics
  (Tables 2 and 3, c_veh and delta);
- :mod:`~railtherm.study.classmodel`, :mod:`~railtherm.study.classvalidation`: the class
  reference model and its leave-one-out validation;
- :mod:`~railtherm.study.scenario`, :mod:`~railtherm.study.simulate`,
  :mod:`~railtherm.study.predictions`: heat-up, energy and peak power with bands;
- :mod:`~railtherm.study.reference`: published values compared with railtherm's fits;
- :mod:`~railtherm.study.identifiability`: what the data determine of a written fit;
- :mod:`~railtherm.study.sindy`: the optional sparse-regression cross-check of a fit;
- :mod:`~railtherm.study.design`: the predicted uncertainty of a planned tunnel programme.
"""
