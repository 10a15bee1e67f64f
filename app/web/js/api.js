// The public /api/v1, as any client calls it: the clinic's key in X-API-Key, kept for
// this browser tab only (sessionStorage); errors are RFC 9457 problem+json.
const KEY = 'calf-nurbs-api-key';

export const apiKey = {
  get: () => sessionStorage.getItem(KEY),
  set: (value) => sessionStorage.setItem(KEY, value),
  clear: () => sessionStorage.removeItem(KEY),
};

export class ApiError extends Error {
  constructor(problem, status) {
    super(problem.detail || problem.title || `HTTP ${status}`);
    this.problem = problem;
    this.status = status;
  }
}

function headers(extra = {}) {
  const out = { ...extra };
  const key = apiKey.get();
  if (key) out['X-API-Key'] = key;
  return out;
}

async function problemOf(response) {
  try {
    return await response.json();
  } catch {
    return { title: response.statusText || 'Request failed', detail: `HTTP ${response.status}` };
  }
}

export async function api(path, { method = 'GET', json, accept, raw = false } = {}) {
  const init = { method, headers: headers(accept ? { Accept: accept } : {}) };
  if (json !== undefined) {
    init.body = JSON.stringify(json);
    init.headers['Content-Type'] = 'application/json';
  }
  const response = await fetch(`/api/v1${path}`, init);
  if (!response.ok) throw new ApiError(await problemOf(response), response.status);
  if (raw) return response;
  if (response.status === 204) return null;
  const type = response.headers.get('content-type') || '';
  return type.includes('json') ? response.json() : response.text();
}

// multipart upload with byte progress (fetch cannot report upload progress)
export function uploadScan(file, fields, onProgress) {
  return new Promise((resolve, reject) => {
    const form = new FormData();
    form.append('file', file, file.name);
    for (const [name, value] of Object.entries(fields)) if (value !== '' && value != null) form.append(name, value);
    const xhr = new XMLHttpRequest();
    xhr.open('POST', '/api/v1/scans');
    for (const [name, value] of Object.entries(headers())) xhr.setRequestHeader(name, value);
    xhr.upload.onprogress = (event) => { if (event.lengthComputable) onProgress(event.loaded / event.total); };
    xhr.onload = () => {
      let body = {};
      try { body = JSON.parse(xhr.responseText); } catch { body = { title: 'Upload failed', detail: xhr.statusText }; }
      if (xhr.status >= 200 && xhr.status < 300) resolve(body); else reject(new ApiError(body, xhr.status));
    };
    xhr.onerror = () => reject(new ApiError({ title: 'Network error', detail: 'the server could not be reached' }, 0));
    xhr.send(form);
  });
}

// a file from the API (with the key in a header, never in a URL) saved by the browser
export async function download(path, filename, accept) {
  const response = await api(path, { raw: true, accept });
  const blob = await response.blob();
  const url = URL.createObjectURL(blob);
  const link = document.createElement('a');
  link.href = url;
  link.download = filename;
  document.body.append(link);
  link.click();
  link.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10000);
}
