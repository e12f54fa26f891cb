"""Run drivers: one per model (``static``, ``flow``, ``coupled``), the time loop (``march``), mesh
convergence studies (``convergence``) and ``dispatch`` (``polypore run``: which driver a case needs)."""
