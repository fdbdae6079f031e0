// The access token for writes: pasted once, kept in this tab's session storage (gone when the tab closes),
// sent only in the Authorization header. The server never puts a token in a page, a URL or a cookie.
const KEY = 'modb-token';

export const token = {
  get: () => sessionStorage.getItem(KEY),
  set: (value) => sessionStorage.setItem(KEY, value.trim()),
  forget: () => sessionStorage.removeItem(KEY),
  headers: () => (sessionStorage.getItem(KEY) ? { Authorization: `Bearer ${sessionStorage.getItem(KEY)}` } : {}),
};

// The token panel: a password field, use / forget, and whether one is set.
export function tokenPanel(input, useButton, forgetButton, stateText) {
  const show = () => {
    stateText.textContent = token.get() ? 'a token is set for this tab' : 'none: reading only';
    forgetButton.hidden = !token.get();
  };
  useButton.addEventListener('click', () => {
    if (input.value.trim()) token.set(input.value);
    input.value = '';
    show();
  });
  forgetButton.addEventListener('click', () => { token.forget(); show(); });
  show();
}
