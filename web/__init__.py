"""The viser review app: a scenario or plan in 3-D in the browser, with time scrubbing, disturbance
plots, goal editing and re-planning, and shareable recordings."""

from proxplan.web.app import ReviewApp, prepare
from proxplan.web.review_data import ReviewData, load_input, load_plan_file, review_from_plan_result

__all__ = ["ReviewApp", "ReviewData", "load_input", "load_plan_file", "prepare", "review_from_plan_result"]
