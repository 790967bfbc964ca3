1; % run_walking3lp.m: a script file (not a function file), so it may define helpers below.
%
% walkrepro's driver of Walking3LP (github.com/salmanfaraji/Walking3LP), the MATLAB code of
% Paper II's first author: it calls Walking3LP's own functions on three parameter sets and
% writes their 3LP matrices and gains to a JSON fixture for tests/external/test_walking3lp.py.
% Written for walkrepro; no line of the author's code is copied here.
%
% Usage (from the walkrepro root; see README.md next to this file):
%   octave --no-gui --norc --quiet tests/external/walking3lp/run_walking3lp.m \
%       <walking3lp checkout> <fixture.json> [<commit>]
%
% What it calls, all from the checkout: initialize, coman_ratios, model_geom, create_model
% (full_model, get_maple_SS), the gait of create_gait (solution), create_controllers and
% time_projection (its disc and cont closures). Everything else here only arranges inputs
% and writes numbers.

args = argv();
if numel(args) < 2
  error("usage: run_walking3lp.m <walking3lp checkout> <fixture.json> [<commit>]");
end
root = args{1};
out_path = args{2};
commit = "63d55a6359fe0f996d2621b31a68e8f1f33e03ee";
if numel(args) >= 3
  commit = args{3};
end
if root(end) ~= "/"
  root = [root "/"];
end
addpath(root);
initialize(root);   % the author's path set-up: basic, anatomy, maple, tools
pkg load control    % dlqr, called by time_projection

T = 0.4;                 % step time [s], Paper II
step_width = 0.25;       % lateral foot spacing at touchdown [m], Paper II
speeds = [0 0.1 0.2];    % commanded speeds [m/s]
n_phases = 100;          % phase grid t_i = i T / n, i = 0 .. n-1 (walkrepro's table grid)
substep_fractions = [0.25 0.5 0.75];

% The three parameter sets. COMAN: the author's anatomy/coman_ratios.m through
% tools/model_geom.m, exactly as the GUI builds it (mass and "height" from the ratios file).
ratios = coman_ratios();
coman = model_geom(ratios.M, ratios.L, ratios);
coman_point = coman;
coman_point.I2 = 0;
coman_point.I3 = 0;
% walkrepro's own COMAN set: walkrepro.papers.faraji.openloop.threelp_params_from_robot
% (load_robot("coman")), the default of the faraji controller (leg_inertia=True). The test
% checks these literals against walkrepro's current value (17 significant digits: exact).
own = coman;
own.m1 = 16.5;
own.m2 = 6.750000000000001;
own.h1 = 0.5198151849;
own.h2 = 0.2138198690022029;
own.h3 = 0.14244787274631632;
own.h4 = 0;
own.pw = 0.07;
own.I2 = 0.26460952737406956;
own.I3 = 0.26460952737406956;
sets = {"coman_walking3lp", coman; "coman_walking3lp_point_legs", coman_point; ...
        "coman_walkrepro", own};

function s = jnum(x)
  % One double as JSON: 17 significant digits round-trip exactly.
  if ~isfinite(x)
    error("non-finite number %g", x);
  end
  s = sprintf("%.17g", x);
end

function s = jvec(v)
  v = v(:).';
  parts = arrayfun(@jnum, v, "UniformOutput", false);
  s = ["[" strjoin(parts, ", ") "]"];
end

function s = jmat(A)
  % A matrix as a list of its rows.
  rows = cell(1, size(A, 1));
  for i = 1:size(A, 1)
    rows{i} = jvec(A(i, :));
  end
  s = ["[" strjoin(rows, ",\n ") "]"];
end

function s = jstack(C)
  % A cell array of matrices as a list of matrices.
  s = ["[" strjoin(cellfun(@jmat, C, "UniformOutput", false), ",\n") "]"];
end

function s = jstr(x)
  s = ["\"" strrep(x, "\"", "\\\"") "\""];
end

function s = jobj(keys, vals)
  % keys: cell of names; vals: cell of JSON strings.
  parts = cell(1, numel(keys));
  for i = 1:numel(keys)
    parts{i} = [jstr(keys{i}) ": " vals{i}];
  end
  s = ["{" strjoin(parts, ",\n") "}"];
end

function G = gain_of(feedback, AH, BH)
  % The linear map e -> U of one of time_projection's closures, column by column:
  % U = feedback(X, X0, AH, BH) with X = X0 = e (8 unit errors). U holds the corrections of
  % X(s.cont.input) = [H2y H2x rH2y rH2x].
  G = zeros(4, 8);
  for i = 1:8
    e = zeros(8, 1);
    e(i) = 1;
    G(:, i) = feedback(e, e, AH, BH);
  end
end

function d = dlqr_record(s)
  % Step-start DLQR of create_controllers / time_projection, given s.cont.Q and s.cont.R.
  [disc, ~, ~, data] = time_projection(s.cont.A, s.cont.B, s.cont.Q, s.cont.R, s.cont.Ch);
  G = gain_of(disc, s.cont.A, s.cont.B);
  d = jobj({"Q", "R", "K", "eig_re", "eig_im", "step_start_gain"}, ...
           {jmat(s.cont.Q), jmat(s.cont.R), jmat(data.K), jvec(real(data.E)), ...
            jvec(imag(data.E)), jmat(G)});
end

set_json = cell(1, rows(sets));
for k = 1:rows(sets)
  model = sets{k, 2};
  % Single support only (Tds = 0), as in Paper II: create_model(model, Tds, Tstep).
  s = create_model(model, 0, T);
  s.step_width = step_width;
  s.gait = s.create_gait(s, 0, 0);   % free ankles: CoP fixed at the ankle (cop1 = cop2 = 0)
  mg = (model.m1 + 2 * model.m2) * model.g;
  params = jobj({"m1", "m2", "h1", "h2", "h3", "h4", "pw", "I2", "I3", "g", "rg", "theta", "slope"}, ...
                {jnum(model.m1), jnum(model.m2), jnum(model.h1), jnum(model.h2), jnum(model.h3), ...
                 jnum(model.h4), jnum(model.pw), jnum(model.I2), jnum(model.I3), jnum(model.g), ...
                 jnum(model.rg), jnum(model.theta), jnum(model.slope)});

  gaits = cell(1, numel(speeds));
  for j = 1:numel(speeds)
    gaits{j} = jobj({"speed", "start"}, {jnum(speeds(j)), jvec(s.gait(speeds(j)))});
  end

  subs = cell(1, numel(substep_fractions));
  for j = 1:numel(substep_fractions)
    t0 = substep_fractions(j) * T;
    subs{j} = jobj({"t0", "start_to_t0", "t0_to_end"}, ...
                   {jnum(t0), jmat(s.H(0, t0)), jmat(s.H(t0, T - t0))});
  end

  % The paper's weights (walkrepro's default_weights, the GUI's Qx and Qr with the model's
  % own m g): Q = diag(1/h1^2 on positions, 1/(g h1) on velocities), R = diag(1 1 0 0)/(m g)^2.
  Qx = diag([ones(4, 1) / model.h1^2; ones(4, 1) / (model.g * model.h1)]);
  s = create_controllers(s, Qx, diag([1 1 0 0]) / mg^2);
  dlqr_paper = dlqr_record(s);
  % A weight with R_ww ~= 0, where time_projection's cross term matters.
  s_identity = create_controllers(s, Qx, eye(4) / mg^2);
  dlqr_identity = dlqr_record(s_identity);

  % Time projection over the phase: the cont closure with the remaining-step maps that
  % create_controllers passes it (s.M s.T H(t, T-t) s.S and its input columns).
  [~, cont] = time_projection(s.cont.A, s.cont.B, s.cont.Q, s.cont.R, s.cont.Ch);
  phases = T * (0:n_phases - 1) / n_phases;
  tp = cell(1, n_phases);
  foot = cell(1, n_phases);
  foot_rel = cell(1, n_phases);
  for i = 1:n_phases
    t = phases(i);
    HT = s.H(t, T - t);
    G = gain_of(cont, s.M * s.T * HT * s.S, s.M * s.T * HT(:, s.cont.input));
    tp{i} = G;
    % Footstep gains (Fig. 13B): the 3LP from the error e at t to the end of the step under
    % this correction, X(T) - nominal = H(t, T-t) (S e + inputs U); stance foot fixed.
    dX = HT * s.S + HT(:, s.cont.input) * G;
    foot{i} = dX(1:2, :);                   % swing foot f(T) [m per unit e]
    foot_rel{i} = dX(1:2, :) - dX(3:4, :);  % f(T) - p(T), as the GUI's gain panel
  end

  set_json{k} = jobj( ...
    {"name", "params", "transition", "substeps", "error_map_A", "error_map_B", "gaits", ...
     "dlqr", "dlqr_identity_R", "phases", "tp_gain", "footstep_swing", ...
     "footstep_swing_minus_pelvis"}, ...
    {jstr(sets{k, 1}), params, jmat(s.H(0, T)), ["[" strjoin(subs, ",\n") "]"], ...
     jmat(s.cont.A), jmat(s.cont.B), ["[" strjoin(gaits, ",\n") "]"], dlqr_paper, ...
     dlqr_identity, jvec(phases), jstack(tp), jstack(foot), jstack(foot_rel)});
end

[~, info] = pkg("list");
control_version = "";
for i = 1:numel(info)
  if strcmp(info{i}.name, "control")
    control_version = info{i}.version;
  end
end
provenance = jobj( ...
  {"repository", "commit", "octave", "octave_control", "driver", "regenerate"}, ...
  {jstr("https://github.com/salmanfaraji/Walking3LP"), jstr(commit), jstr(OCTAVE_VERSION), ...
   jstr(control_version), jstr("tests/external/walking3lp/run_walking3lp.m"), ...
   jstr("see tests/external/walking3lp/README.md")});
setup = jobj({"step_time", "step_width", "speeds", "substep_fractions", "n_phases"}, ...
             {jnum(T), jnum(step_width), jvec(speeds), jvec(substep_fractions), jnum(n_phases)});
text = [jobj({"provenance", "setup", "sets"}, ...
             {provenance, setup, ["[" strjoin(set_json, ",\n") "]"]}) "\n"];
fid = fopen(out_path, "w");
fputs(fid, text);
fclose(fid);
printf("wrote %s (%d bytes), sha256 %s\n", out_path, numel(text), hash("sha256", text));
