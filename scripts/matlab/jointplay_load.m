function run = jointplay_load(file, case_label)
% JOINTPLAY_LOAD  A jointplay run file (HDF5) as a struct, in MATLAB or GNU Octave.
%
%   run = jointplay_load('out/pendulum.h5')
%   run = jointplay_load('out/ablation.h5', 'no-friction')   % a case of a comparison study
%
% The struct holds the run's samples as `jointplay export --format mat` writes them:
%   run.time                      n x 1, s
%   run.bodies_bob_position       n x 3, one matrix per dataset (its path with / as _)
%   run.units.bodies_bob_position 'm', each variable's SI unit
%   run.columns.bodies_bob_position  each column's observable path, a row per column
% e.g. plot(run.time, run.bodies_bob_position(:, 1)).
%
% It runs `jointplay export` (the program on the PATH, or the one the environment variable
% JOINTPLAY names) into a temporary folder and loads the MAT file, so it reads whatever the
% program reads and says what the program says of a file it cannot: an analysis study's file,
% a comparison study's file without a case (the error lists the cases), a file that is not
% jointplay's. Without the program, MATLAB's h5read reads the HDF5 file directly (the book's
% "Use the data from MATLAB and Python").
  if nargin < 2
    case_label = '';
  end
  exe = getenv('JOINTPLAY');
  if isempty(exe)
    exe = 'jointplay';
  end
  % The names go into a shell command: refuse those a shell would read.
  if any(ismember([file case_label], '"$`'))
    error('jointplay_load:name', 'jointplay_load: a file name or case with " $ or ` is not passed to the shell');
  end
  out = tempname();
  mkdir(out);
  cmd = sprintf('"%s" export "%s" --format mat --out "%s"', exe, file, out);
  if ~isempty(case_label)
    cmd = sprintf('%s --case "%s"', cmd, case_label);
  end
  [status, text] = system([cmd ' 2>&1']);
  if status ~= 0
    remove_folder(out);
    error('jointplay_load:export', 'jointplay_load(%s): %s', file, strtrim(text));
  end
  [~, stem] = fileparts(file);
  if ~isempty(case_label)
    stem = [stem '-' case_label];
  end
  try
    run = load(fullfile(out, [stem '.mat']));
  catch err
    remove_folder(out);
    rethrow(err);
  end
  remove_folder(out);
end

function remove_folder(out)
  files = dir(fullfile(out, '*.mat'));
  for k = 1:numel(files)
    delete(fullfile(out, files(k).name));
  end
  rmdir(out);
end
